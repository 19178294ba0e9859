// The firmware in float (Cortex-M4F) keeps what the film estimate needs: lithium conserved
// over a cycle, iterations that end at float's floor, a growth sum that still grows late in
// the cell's life. Each test compares with the double build or with a sum it can compute.
#include <gtest/gtest.h>

#include <cmath>

#include "bms/fw/model/dual.hpp"
#include "bms/fw/estimation/film_growth_identifier.hpp"
#include "bms/fw/model/paper_cell.hpp"
#include "bms/fw/model/reduced_cell.hpp"

namespace {

using CellF = bms::fw::ReducedCell<float>;
using CellD = bms::fw::ReducedCell<double>;

// Half a CCCV cycle's worth of constant-current ticks each way, same input to both builds.
template <typename Cell, typename S>
void cycle(Cell& c, int ticks) {
  for (int k = 0; k < ticks; ++k) c.step_current(S(2.5), S(3.4e-3), S(0.2));
  for (int k = 0; k < ticks; ++k) c.step_current(S(-2.5), S(3.4e-3), S(0.2));
}

TEST(FloatNumerics, InventoryConservedOverACycle) {
  CellF f;
  CellD d;
  f.init_default();
  d.init_default();
  cycle<CellF, float>(f, 15000);
  cycle<CellD, double>(d, 15000);
  const double rel = std::fabs(static_cast<double>(f.solid_inventory_mol()) - d.solid_inventory_mol()) /
                     d.solid_inventory_mol();
  // Absolute concentrations updated in place drifted by 2.3e-4 of the inventory per cycle
  // (1 % of inventory is 3-12 mV); increments with a carried compensation keep it near 1e-6.
  EXPECT_LT(rel, 1e-5) << "float inventory off double's by " << rel;
  EXPECT_NEAR(static_cast<double>(f.li_loss_mol()), d.li_loss_mol(), 1e-4 * d.li_loss_mol());
}

TEST(FloatNumerics, VoltageStepConvergesInFloat) {
  CellF f;
  f.init_default();
  for (int k = 0; k < 2000; ++k) f.step_current(2.5f, 3.4e-3f, 0.2f);
  const float v = f.peek_voltage(1.0f, 3.4e-3f, 0.2f);
  int capped = 0;
  for (int k = 0; k < 200; ++k) {
    const auto r = f.step_voltage(v, 3.4e-3f, 0.2f);
    if (!r.converged) ++capped;
    if (k > 0) {
      EXPECT_LE(r.newton_iterations, 3);  // the first tick's current jumps by 1.5 A
    }
  }
  EXPECT_EQ(capped, 0);
  EXPECT_GT(CellF::kVoltageToleranceV, 1e-6);  // float's floor, not double's 1e-9
  EXPECT_EQ(CellD::kVoltageToleranceV, 1e-9);
}

TEST(FloatNumerics, ResyncReachesItsToleranceInFloat) {
  CellF f;
  f.init_default();
  for (int k = 0; k < 3000; ++k) f.step_current(2.5f, 3.4e-3f, 0.2f);  // from full, 600 s of discharge
  const float v = f.peek_voltage(-0.2f, 3.4e-3f, 0.2f) + 0.005f;
  ASSERT_TRUE(f.resync(v, -0.2f, 3.4e-3f, 0.2f, f.solid_inventory_mol() * 1.005f));
  EXPECT_LT(std::fabs(f.peek_voltage(-0.2f, 3.4e-3f, 0.2f) - v), static_cast<float>(CellF::kResyncToleranceV));
}

TEST(FloatNumerics, GrowthSumKeepsGrowingLateInLife) {
  bms::fw::FilmGrowthIdentifier<float>::Config c;
  c.r_film_nominal_ohm_m2 = static_cast<float>(bms::fw::paper::kInitialFilm_ohm_m2);
  c.growth_nominal_ohm_m2_per_a_m3_s = 1e-9f;
  bms::fw::FilmGrowthIdentifier<float> id(c);
  auto s = id.save();
  s.growth_ohm_m2 = 0.05f;  // a film grown 15 times over: float's step there is 3.7e-9
  ASSERT_TRUE(id.restore(s));
  const int ticks = 100000;
  for (int k = 0; k < ticks; ++k) id.propagate(-10.0f, 0.2f);  // 2e-9 ohm m2 per tick
  const double grown = static_cast<double>(id.growth_ohm_m2()) - 0.05;
  EXPECT_NEAR(grown, ticks * 2e-9, 1e-3 * ticks * 2e-9);
}

// The single-precision form of the open-circuit potentials (paper_cell.hpp, SplitSum) is a
// second spelling of the same functions: every value within float's scatter of double's, and
// no systematic error (mean over 2e-3 of stoichiometry; 2-5e-7 V with plainly rounded
// coefficients, a third of the film's signal over a charge).
TEST(FloatNumerics, OpenCircuitPotentialsInFloatMatchDouble) {
  namespace p = bms::fw::paper;
  double worst = 0.0, worst_mean = 0.0;
  for (int w = 1; w <= 19; ++w) {
    double sum_n = 0.0, sum_p = 0.0;
    const int n = 1000;
    for (int k = 0; k < n; ++k) {
      const float x = static_cast<float>(0.05 * w + 2e-6 * k);
      const double xd = static_cast<double>(x);
      const double en = static_cast<double>(p::ocp_negative_v(x)) - p::ocp_negative_v(xd);
      const double ep = static_cast<double>(p::ocp_positive_v(x)) - p::ocp_positive_v(xd);
      worst = std::fmax(worst, std::fmax(std::fabs(en), std::fabs(ep)));
      sum_n += en;
      sum_p += ep;
    }
    worst_mean = std::fmax(worst_mean, std::fmax(std::fabs(sum_n / n), std::fabs(sum_p / n)));
  }
  EXPECT_LT(worst, 8e-6);
  EXPECT_LT(worst_mean, 2e-7);
  // The float build's CV step differentiates them: dU/dx agrees with double's.
  const auto df = p::ocp_negative_v(bms::fw::Dual<float>(0.5f, 1.0f));
  const auto dd = p::ocp_negative_v(bms::fw::Dual<double>(0.5, 1.0));
  EXPECT_NEAR(static_cast<double>(df.d), dd.d, 1e-3 * std::fabs(dd.d) + 2e-5);
}

}  // namespace
