// The truth model's cathode particle-size distribution (About:Energy knee): off it
// adds nothing; on, charge is conserved across the populations, the total surface area is the
// cell's, and small particles fill before large ones on discharge.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <vector>

#include "dfn/dfn_solver.hpp"
#include "io/input_error.hpp"
#include "sim/cell_catalog.hpp"
#include "sim/cycler.hpp"

namespace bms {
namespace {

const DfnMesh kCoarse{6, 3, 6, 6};

// The About:Energy cell without its side reaction (the paper's, which every cell has): an
// anode size distribution is not available together with the side reaction.
CellParameters ae_cell() {
  CellParameters c = load_cell("aboutenergy");
  c.side.enabled = false;
  return c;
}

// Mean stoichiometry of one cathode population over the electrode, from its shells.
double population_stoich(const DfnModel& m, const double* y, int pop) {
  const int nr = m.mesh().n_r;
  double moles = 0.0, volume = 0.0;
  for (int e = m.mesh().n_neg; e < m.n_electrode_nodes(); ++e) {
    // Shell volumes are mass-matrix entries: sum of c * shell volume / sum of shell volumes.
    for (int r = 0; r < nr; ++r) {
      const int i = m.idx_cs_pop(e, pop, r);
      moles += y[i] * m.mass()[i];
      volume += m.mass()[i];
    }
  }
  return moles / volume / m.cell().positive.max_concentration_mol_m3;
}

TEST(ParticleSize, OffAddsNoStateAndLeavesTheResidualUnchanged) {
  const CellParameters cell = ae_cell();
  DfnModel plain(cell, kCoarse, 298.15);
  ModelEffects off;
  off.particle_size_populations = 5;  // a node count without a spread changes nothing
  DfnModel same(cell, kCoarse, 298.15, off);
  ASSERT_EQ(plain.size(), same.size());
  EXPECT_EQ(same.n_populations(kCoarse.n_neg), 1);
  const auto ic = default_initial_conditions(cell);
  auto y = plain.initial_state(ic.stoich_neg, ic.stoich_pos, ic.electrolyte_mol_m3, 0.0);
  for (size_t i = 0; i < y.size(); ++i) y[i] *= 1.0 + 1e-4 * std::sin(static_cast<double>(i));
  std::vector<double> g1(y.size()), g2(y.size());
  plain.set_control({ControlKind::current, 2.0});
  same.set_control({ControlKind::current, 2.0});
  plain.eval_g(0.0, y.data(), g1.data());
  same.eval_g(0.0, y.data(), g2.data());
  for (size_t i = 0; i < y.size(); ++i) ASSERT_EQ(g1[i], g2[i]) << "row " << i;
}

// With a vanishing spread and every population in population 0's state, the shared rows
// (electrolyte, potentials, particles of population 0) are the plain model's.
TEST(ParticleSize, VanishingSpreadIsThePlainModel) {
  const CellParameters cell = ae_cell();
  DfnModel plain(cell, kCoarse, 298.15);
  for (int variant = 0; variant < 2; ++variant) {
    ModelEffects eff;
    (variant == 0 ? eff.particle_size_sigma : eff.particle_size_negative_sigma) = 1e-9;
    DfnModel m(cell, kCoarse, 298.15, eff);
    ASSERT_GT(m.size(), plain.size());
    const auto ic = default_initial_conditions(cell);
    auto y = plain.initial_state(ic.stoich_neg, ic.stoich_pos, ic.electrolyte_mol_m3, 0.0);
    for (size_t i = 0; i < y.size(); ++i) y[i] *= 1.0 + 1e-3 * std::sin(static_cast<double>(i));
    for (int e = 0; e < plain.n_electrode_nodes(); ++e) y[plain.idx_j(e)] = 0.5 * std::cos(e);
    std::vector<double> ym(m.size(), 0.0);
    std::copy(y.begin(), y.end(), ym.begin());
    for (int e = 0; e < m.n_electrode_nodes(); ++e)
      for (int p = 1; p < m.n_populations(e); ++p) {
        ym[m.idx_j_pop(e, p)] = y[plain.idx_j(e)];
        for (int r = 0; r < kCoarse.n_r; ++r) ym[m.idx_cs_pop(e, p, r)] = y[plain.idx_cs(e, r)];
      }
    std::vector<double> g1(plain.size()), g2(m.size());
    plain.set_control({ControlKind::current, 2.0});
    m.set_control({ControlKind::current, 2.0});
    plain.eval_g(0.0, y.data(), g1.data());
    m.eval_g(0.0, ym.data(), g2.data());
    for (int i = 0; i < plain.size(); ++i)
      ASSERT_NEAR(g1[i], g2[i], 1e-6 * (1.0 + std::abs(g1[i]))) << "variant " << variant << " row " << i;
    // ... and every other population's rows repeat population 0's.
    for (int e = 0; e < m.n_electrode_nodes(); ++e)
      for (int p = 1; p < m.n_populations(e); ++p) {
        ASSERT_NEAR(g2[m.idx_j_pop(e, p)], g1[plain.idx_j(e)], 1e-6 * (1.0 + std::abs(g1[plain.idx_j(e)])))
            << "variant " << variant << " node " << e;
        for (int r = 0; r < kCoarse.n_r; ++r)
          ASSERT_NEAR(g2[m.idx_cs_pop(e, p, r)], g1[plain.idx_cs(e, r)], 1e-6 * (1e-20 + std::abs(g1[plain.idx_cs(e, r)])))
              << "variant " << variant << " node " << e << " shell " << r;
      }
  }
}

TEST(ParticleSize, PopulationsKeepTheSurfaceAreaAndSpreadTheRadius) {
  const CellParameters cell = ae_cell();
  for (int n : {3, 5}) {
    ModelEffects eff;
    eff.particle_size_sigma = 0.4;
    eff.particle_size_populations = n;
    DfnModel m(cell, kCoarse, 298.15, eff);
    ASSERT_EQ(m.n_populations(kCoarse.n_neg), n);
    EXPECT_EQ(m.n_populations(0), 1);  // anode untouched without its own sigma
    double weight = 0.0, inverse_radius = 0.0, lo = 1e9, hi = 0.0;
    for (int p = 0; p < n; ++p) {
      weight += m.population_volume_fraction(false, p);
      inverse_radius += m.population_volume_fraction(false, p) / m.population_radius_scale(false, p);
      lo = std::min(lo, m.population_radius_scale(false, p));
      hi = std::max(hi, m.population_radius_scale(false, p));
    }
    EXPECT_NEAR(weight, 1.0, 1e-12);
    EXPECT_NEAR(inverse_radius, 1.0, 1e-12);  // Sauter mean = the cell's radius
    EXPECT_GT(hi / lo, std::exp(2.0 * 0.4));   // nodes beyond +-1 sigma
  }
}

TEST(ParticleSize, DischargeConservesChargeAndFillsSmallParticlesFirst) {
  const CellParameters cell = ae_cell();
  ModelEffects eff;
  eff.particle_size_sigma = 0.5;
  eff.particle_size_negative_sigma = 0.3;  // both electrodes: the anode's states come first
  DfnModel m(cell, kCoarse, 298.15, eff);
  ASSERT_EQ(m.n_populations(0), 3);
  DfnSolver solver(m, SolverSettings{});
  m.set_control({ControlKind::current, 0.0});
  const auto ic = default_initial_conditions(cell);
  solver.start(0.0, m.initial_state(ic.stoich_neg, ic.stoich_pos, ic.electrolyte_mol_m3, 0.0));
  const double inventory0 = m.lithium_inventory_mol(solver.y().data());
  const double cathode0 = m.mean_stoich(solver.y().data(), false);
  const double negative0 = m.mean_stoich(solver.y().data(), true);
  solver.switch_control({ControlKind::current, 2.0}, StopConditions{});  // about 1C
  ASSERT_EQ(solver.advance_to(1200.0), DfnSolver::Result::reached);
  const double* y = solver.y().data();
  const auto& p = cell.positive;
  const double cathode_mol = (m.mean_stoich(y, false) - cathode0) * p.max_concentration_mol_m3 * p.solid_fraction *
                             p.thickness_m * cell.electrode_area_m2;
  const double passed_mol = y[m.idx_charge()] * 3600.0 / kFaradayC_mol;
  ASSERT_GT(passed_mol, 0.0);
  EXPECT_NEAR(cathode_mol, passed_mol, 1e-4 * passed_mol);
  EXPECT_NEAR(m.lithium_inventory_mol(y), inventory0, 1e-6 * inventory0);
  const auto& n = cell.negative;
  const double anode_mol = (negative0 - m.mean_stoich(y, true)) * n.max_concentration_mol_m3 * n.solid_fraction *
                           n.thickness_m * cell.electrode_area_m2;
  EXPECT_NEAR(anode_mol, passed_mol, 1e-4 * passed_mol);
  // Smallest population (shortest diffusion time) is fuller than the largest.
  int small = 0, large = 0;
  for (int q = 1; q < m.n_populations(kCoarse.n_neg); ++q) {
    if (m.population_radius_scale(false, q) < m.population_radius_scale(false, small)) small = q;
    if (m.population_radius_scale(false, q) > m.population_radius_scale(false, large)) large = q;
  }
  EXPECT_GT(population_stoich(m, y, small), population_stoich(m, y, large) + 1e-3);
}

TEST(ParticleSize, BadValuesAreInputErrors) {
  const CellParameters cell = ae_cell();
  ModelEffects eff;
  eff.particle_size_sigma = -0.1;
  EXPECT_THROW(DfnModel(cell, kCoarse, 298.15, eff), InputError);
  eff.particle_size_sigma = NAN;
  EXPECT_THROW(DfnModel(cell, kCoarse, 298.15, eff), InputError);
  eff.particle_size_sigma = 0.3;
  eff.particle_size_populations = 4;
  EXPECT_THROW(DfnModel(cell, kCoarse, 298.15, eff), InputError);
  // The film row follows the plain anode particle only: an anode spread refuses the side reaction.
  eff.particle_size_populations = 3;
  eff.particle_size_negative_sigma = 0.3;
  CellParameters with_side = cell;
  with_side.side.enabled = true;
  EXPECT_THROW(DfnModel(with_side, kCoarse, 298.15, eff), InputError);
  DfnModel m(cell, kCoarse, 298.15, eff);
  EXPECT_THROW(m.set_side_reaction_enabled(true), InputError);
}

}  // namespace
}  // namespace bms
