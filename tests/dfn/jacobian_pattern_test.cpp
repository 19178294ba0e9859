// The Jacobian's structural pattern (sparsity tracers, O(nonzeros)) holds every entry the
// former numerical probe found, with and without the effects that add states, and few more.
#include <gtest/gtest.h>

#include <algorithm>

#include "cell/paper_cell.hpp"
#include "dfn/dfn_solver.hpp"
#include "sim/cycler.hpp"

namespace bms {
namespace {

struct Counts {
  long structural = 0, probed = 0, missing = 0;
};

Counts compare_patterns(const ModelEffects& effects, const DfnMesh& mesh) {
  const CellParameters cell = make_paper_cell();
  DfnModel m(cell, mesh, cell.thermal.ambient_temperature_k, effects);
  const auto ic = default_initial_conditions(cell);
  const auto y0 = m.initial_state(ic.stoich_neg, ic.stoich_pos, ic.electrolyte_mol_m3, ic.r_film_ohm_m2);
  const auto s = structural_jacobian_pattern(m, y0);
  const auto p = probed_jacobian_pattern(m, y0);
  Counts c;
  for (int col = 0; col < m.size(); ++col) {
    c.structural += static_cast<long>(s[col].size());
    c.probed += static_cast<long>(p[col].size());
    for (int row : p[col])
      if (!std::binary_search(s[col].begin(), s[col].end(), row)) ++c.missing;
  }
  return c;
}

TEST(JacobianPattern, StructuralHoldsTheProbedPattern) {
  const DfnMesh mesh{6, 4, 6, 5};
  ModelEffects thermal;
  thermal.thermal_h_w_per_k = 0.05;
  ModelEffects hysteresis;
  hysteresis.hysteresis_v = 0.01;
  ModelEffects particles;
  particles.particle_size_sigma = 0.3;
  ModelEffects all = thermal;
  all.hysteresis_v = 0.01;
  all.particle_size_sigma = 0.3;
  all.contact_resistance_ohm = 0.01;
  for (const ModelEffects& e : {ModelEffects{}, thermal, hysteresis, particles, all}) {
    const Counts c = compare_patterns(e, mesh);
    SCOPED_TRACE(testing::Message() << "structural " << c.structural << ", probed " << c.probed);
    EXPECT_EQ(c.missing, 0);
    // Structural entries the probe cannot see are few (terms that vanish at the probed states).
    EXPECT_LE(c.structural, c.probed + c.probed / 5);
  }
}

}  // namespace
}  // namespace bms
