// The electrolyte thermodynamic factor TDF(c_e) multiplies the diffusion term of the ionic
// current: i_e = -kappa (grad phi_e - 2 (1 - t+) RT/F TDF grad ln c_e). Limiting case: with no
// current anywhere (no applied current, reactions frozen), grad phi_e equals the diffusion
// term, so across a concentration profile phi_e(L) - phi_e(0) = 2 (1 - t+) RT/F times the
// integral of TDF(c)/c dc: nu TDF ln(c_L / c_0) for a constant factor.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>

#include "cell/paper_cell.hpp"
#include "dfn/dfn_solver.hpp"
#include "sim/cycler.hpp"

namespace bms {
namespace {

// TDF(c) = a + b c, with its exact derivative.
class LinearFactor final : public ScalarFunction {
 public:
  LinearFactor(double a, double b) : a_(a), b_(b) {}
  double value(double c) const override { return a_ + b_ * c; }
  double derivative(double) const override { return b_; }

 private:
  double a_, b_;
};

constexpr double kC0 = 800.0, kC1 = 1400.0;  // mol/m3 at x = 0 and x = L

// phi_e(L) - phi_e(0) of the consistent state over a linear c_e profile, no current.
double diffusion_potential_v(const ScalarFunctionPtr& factor) {
  CellParameters cell = make_paper_cell();
  cell.side.enabled = false;
  cell.negative.i0_coefficient *= 1e-6;  // reactions nearly frozen: ~1e-6 A/m2 of local-cell current
  cell.positive.i0_coefficient *= 1e-6;
  cell.electrolyte.thermodynamic_factor = factor;
  const DfnMesh mesh{20, 20, 20, 5};
  DfnModel m(cell, mesh, cell.thermal.ambient_temperature_k);
  const auto ic = default_initial_conditions(cell);
  auto y = m.initial_state(ic.stoich_neg, ic.stoich_pos, ic.electrolyte_mol_m3, 0.0);
  const int nx = m.n_x();
  for (int k = 0; k < nx; ++k) y[m.idx_ce(k)] = kC0 + (kC1 - kC0) * (k + 0.5) / nx;
  m.set_control({ControlKind::current, 0.0});
  DfnSolver solver(m, SolverSettings{});
  solver.start(0.0, y);
  return solver.y()[m.idx_phie(nx - 1)] - solver.y()[m.idx_phie(0)];
}

double nu_v() {
  const CellParameters cell = make_paper_cell();
  return 2.0 * (1.0 - cell.electrolyte.transference_number) * kGas_j_mol_k * cell.thermal.ambient_temperature_k /
         kFaradayC_mol;
}

TEST(ThermodynamicFactor, NoCurrentDiffusionPotential) {
  const int nx = 60;
  const double c_first = kC0 + (kC1 - kC0) * 0.5 / nx, c_last = kC0 + (kC1 - kC0) * (nx - 0.5) / nx;
  const double ideal = nu_v() * std::log(c_last / c_first);
  EXPECT_NEAR(diffusion_potential_v(nullptr), ideal, 1e-6 * std::abs(ideal));
  // A constant factor scales it exactly.
  EXPECT_NEAR(diffusion_potential_v(std::make_shared<ConstantFunction>(1.7)), 1.7 * ideal, 1e-6 * std::abs(ideal));
  // A concentration-dependent one: nu (a ln(c_L/c_0) + b (c_L - c_0)); the face average of the
  // finite volumes is second order, well inside 0.1 %.
  const double a = 0.6, b = 1.2e-3;
  const double exact = nu_v() * (a * std::log(c_last / c_first) + b * (c_last - c_first));
  EXPECT_NEAR(diffusion_potential_v(std::make_shared<LinearFactor>(a, b)), exact, 1e-3 * std::abs(exact));
}

}  // namespace
}  // namespace bms
