// A solid diffusivity that depends on the local stoichiometry (the truth's particles take D on
// each shell face): a constant profile is the scalar path, lithium is conserved, and a cathode
// that diffuses slower towards full lithiation ends a discharge earlier.
#include <gtest/gtest.h>

#include <cmath>
#include <memory>
#include <vector>

#include "cell/diffusivity_profile.hpp"
#include "ae_discharge.hpp"
#include "dfn/dfn_solver.hpp"
#include "io/expression.hpp"
#include "io/input_error.hpp"
#include "sim/cell_catalog.hpp"
#include "sim/cycler.hpp"

namespace bms {
namespace {

using ae_discharge::ae_cell;
using ae_discharge::Discharge;
using ae_discharge::kCoarse;

Discharge discharge(const CellParameters& cell, const ModelEffects& effects, double current_a) {
  return ae_discharge::discharge(cell, effects, current_a, 2.5);
}

TEST(DiffusivityProfile, ConstantFactorIsTheScalarPathBitForBit) {
  const CellParameters plain_cell = ae_cell();
  CellParameters with_factor = plain_cell;
  with_factor.positive.solid_diffusivity_factor = std::make_shared<ConstantFunction>(1.0);
  with_factor.negative.solid_diffusivity_factor = std::make_shared<ConstantFunction>(1.0);
  DfnModel plain(plain_cell, kCoarse, 298.15), same(with_factor, kCoarse, 298.15);
  const auto ic = default_initial_conditions(plain_cell);
  auto y = plain.initial_state(ic.stoich_neg, ic.stoich_pos, ic.electrolyte_mol_m3, 0.0);
  for (size_t i = 0; i < y.size(); ++i) y[i] *= 1.0 + 1e-3 * std::sin(static_cast<double>(i));
  std::vector<double> g1(y.size()), g2(y.size());
  plain.set_control({ControlKind::current, 2.0});
  same.set_control({ControlKind::current, 2.0});
  plain.eval_g(0.0, y.data(), g1.data());
  same.eval_g(0.0, y.data(), g2.data());
  for (size_t i = 0; i < y.size(); ++i) ASSERT_EQ(g1[i], g2[i]) << "row " << i;
  const Discharge a = discharge(plain_cell, {}, 2.0), b = discharge(with_factor, {}, 2.0);
  EXPECT_EQ(a.end_s, b.end_s);
  ASSERT_EQ(a.v.size(), b.v.size());
  for (size_t k = 0; k < a.v.size(); ++k) ASSERT_EQ(a.v[k], b.v[k]) << "sample " << k;
}

// The profile's Jacobian is the exact derivative of its residual (dual numbers through the
// factor): a central difference of the residual agrees.
TEST(DiffusivityProfile, FactorDerivativeIsExact) {
  const KneeDiffusivityProfile f(-2.0, 0.6);
  for (double x : {0.1, 0.65, 0.8, 0.95}) {
    const double h = 1e-6;
    EXPECT_NEAR(f.derivative(x), (f.value(x + h) - f.value(x - h)) / (2.0 * h), 1e-5 * (1.0 + std::abs(f.derivative(x))));
  }
  EXPECT_EQ(f.value(0.3), 1.0);
  EXPECT_NEAR(f.value(1.0), 0.01, 1e-15);
  EXPECT_NEAR(f.value(0.8), std::pow(10.0, -1.0), 1e-12);
}

TEST(DiffusivityProfile, SlowerAtFullLithiationEndsTheDischargeEarlier) {
  const CellParameters cell = ae_cell();
  ModelEffects slow;
  slow.diffusivity_profile_positive = -2.0;  // 100 x slower at x = 1 than below the knee
  slow.diffusivity_profile_positive_knee = 0.6;
  const Discharge plain = discharge(cell, {}, 2.0), profiled = discharge(cell, slow, 2.0);
  EXPECT_LT(plain.inventory_drift, 1e-6);
  EXPECT_LT(profiled.inventory_drift, 1e-6);  // flux form: what leaves one shell enters the next
  // The knee comes earlier ...
  EXPECT_LT(profiled.end_s, plain.end_s - 120.0) << profiled.end_s << " vs " << plain.end_s;
  // ... the plateau below the knee (the first half of the discharge) is untouched ...
  const size_t mid = profiled.v.size() / 3;
  EXPECT_NEAR(profiled.v[mid], plain.v[mid], 2e-3);
  // (With this profile the fall itself is sharp: the surface of the slowed particles fills
  // to x = 1 within a minute, 3.05 -> 2.5 V, where the plain model falls over 20 minutes.)
}

TEST(DiffusivityProfile, BpxExpressionIsTakenRelativeToMidRange) {
  const auto f = ExpressionFunction::parse("6.873e-17 * 10 ** (-1.5 * x)", "test");
  const ScalarFunctionPtr rel = relative_to(f, 0.5);
  EXPECT_NEAR(rel->value(0.5), 1.0, 1e-12);
  EXPECT_NEAR(rel->value(1.0), std::pow(10.0, -0.75), 1e-12);
  const ScalarFunctionPtr both = with_knee_profile(rel, -1.0, 0.5);
  EXPECT_NEAR(both->value(1.0), std::pow(10.0, -1.75), 1e-12);
  EXPECT_NEAR(both->derivative(0.7), (both->value(0.7 + 1e-6) - both->value(0.7 - 1e-6)) / 2e-6, 1e-4);
}

TEST(DiffusivityProfile, BadValuesAreInputErrors) {
  const CellParameters cell = ae_cell();
  ModelEffects eff;
  eff.diffusivity_profile_positive = -5.0;
  EXPECT_THROW(DfnModel(cell, kCoarse, 298.15, eff), InputError);
  eff.diffusivity_profile_positive = NAN;
  EXPECT_THROW(DfnModel(cell, kCoarse, 298.15, eff), InputError);
  eff.diffusivity_profile_positive = -1.0;
  eff.diffusivity_profile_positive_knee = 1.0;
  EXPECT_THROW(DfnModel(cell, kCoarse, 298.15, eff), InputError);
}

}  // namespace
}  // namespace bms
