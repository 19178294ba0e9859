// The firmware's reduced-order main-system model: physics it must keep whatever the mesh.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "bms/fw/model/reduced_cell.hpp"

namespace {

using Cell = bms::fw::ReducedCell<double>;

TEST(ReducedCell, RestKeepsOpenCircuitVoltage) {
  Cell c;
  c.init_default();
  const auto first = c.step_current(0.0, bms::fw::paper::kInitialFilm_ohm_m2, 0.2);
  for (int i = 0; i < 100; ++i) {
    const auto r = c.step_current(0.0, bms::fw::paper::kInitialFilm_ohm_m2, 0.2);
    // Only the side reaction moves a resting cell: microvolts over 20 s.
    EXPECT_NEAR(r.voltage_v, first.voltage_v, 1e-5);
  }
  const double ocv = bms::fw::paper::ocp_positive_v(0.1592) - bms::fw::paper::ocp_negative_v(0.8408);
  EXPECT_NEAR(first.voltage_v, ocv, 2e-4);
}

TEST(ReducedCell, ChargeBalanceAndLithiumLoss) {
  // The anode's particles give up the applied charge plus the lithium the side reaction
  // consumes (j_int = j - j_s with j_s < 0); the cathode receives exactly the applied charge.
  Cell c;
  c.init_default();
  const double neg0 = c.mean_stoich_neg(), pos0 = c.mean_stoich_pos();
  const double dt = 0.2, current = 2.5;
  for (int i = 0; i < 3000; ++i) c.step_current(current, bms::fw::paper::kInitialFilm_ohm_m2, dt);
  constexpr double F = bms::fw::kFaradayC_mol;
  namespace p = bms::fw::paper;
  const double vol_n = p::kNegative.solid_fraction * p::kNegative.thickness_m * p::kElectrodeArea_m2;
  const double vol_p = p::kPositive.solid_fraction * p::kPositive.thickness_m * p::kElectrodeArea_m2;
  const double mol_out_n = (neg0 - c.mean_stoich_neg()) * p::kNegative.max_concentration_mol_m3 * vol_n;
  const double mol_in_p = (c.mean_stoich_pos() - pos0) * p::kPositive.max_concentration_mol_m3 * vol_p;
  const double mol_applied = current * dt * 3000 / F;
  EXPECT_NEAR(mol_in_p / mol_applied, 1.0, 1e-9);
  EXPECT_NEAR((mol_out_n - c.state().li_loss_mol) / mol_applied, 1.0, 1e-9);
  EXPECT_GT(c.state().li_loss_mol, 0.0);
}

TEST(ReducedCell, VoltageDrivenStepHitsTheVoltage) {
  Cell c;
  c.init_default();
  for (int i = 0; i < 500; ++i) c.step_current(-2.5, bms::fw::paper::kInitialFilm_ohm_m2, 0.2);
  const double v_target = c.peek_voltage(-1.0, bms::fw::paper::kInitialFilm_ohm_m2, 0.2);
  Cell copy = c;
  const auto r = c.step_voltage(v_target, bms::fw::paper::kInitialFilm_ohm_m2, 0.2);
  EXPECT_TRUE(r.converged);
  EXPECT_LE(r.newton_iterations, Cell::kMaxNewtonIterations);
  EXPECT_NEAR(r.current_a, -1.0, 1e-6);
  EXPECT_NEAR(r.voltage_v, v_target, 1e-8);
  // The same tick driven by the found current gives the same state.
  copy.step_current(r.current_a, bms::fw::paper::kInitialFilm_ohm_m2, 0.2);
  EXPECT_NEAR(copy.state().ce_mol_m3[0], c.state().ce_mol_m3[0], 1e-9);
}

TEST(ReducedCell, FilmResistanceEntersAsMinusJTimesR) {
  Cell c;
  c.init_default();
  for (int i = 0; i < 100; ++i) c.step_current(-2.5, bms::fw::paper::kInitialFilm_ohm_m2, 0.2);
  const double dr = 1e-5;
  const double v0 = c.peek_voltage(-2.5, bms::fw::paper::kInitialFilm_ohm_m2, 0.2);
  const double v1 = c.peek_voltage(-2.5, bms::fw::paper::kInitialFilm_ohm_m2 + dr, 0.2);
  const auto r = c.step_current(-2.5, bms::fw::paper::kInitialFilm_ohm_m2, 0.2);
  EXPECT_NEAR((v1 - v0) / dr, r.markov_v_per_ohm_m2, 1e-3 * std::abs(r.markov_v_per_ohm_m2));
  EXPECT_GT(r.markov_v_per_ohm_m2, 0.8);  // charge: H = -j_n about +0.88 V per ohm m2
}

TEST(ReducedCell, NonFiniteInputLeavesStateUnchanged) {
  Cell c;
  c.init_default();
  c.step_current(2.5, bms::fw::paper::kInitialFilm_ohm_m2, 0.2);
  const Cell::State before = c.state();
  const auto r = c.step_current(std::nan(""), bms::fw::paper::kInitialFilm_ohm_m2, 0.2);
  EXPECT_FALSE(r.valid);
  EXPECT_EQ(std::memcmp(&before, &c.state(), sizeof(before)), 0);
}

TEST(ReducedCell, RestoreRejectsNonFiniteImages) {
  Cell c;
  c.init_default();
  Cell::State bad = c.state();
  bad.ce_mol_m3[1] = std::nan("");
  EXPECT_FALSE(c.restore(bad));
  EXPECT_TRUE(c.restore(c.state()));
}

TEST(ReducedCell, FloatInstantiates) {
  bms::fw::ReducedCell<float> c;
  c.init_default();
  const auto r = c.step_current(2.5f, static_cast<float>(bms::fw::paper::kInitialFilm_ohm_m2), 0.2f);
  EXPECT_TRUE(std::isfinite(r.voltage_v));
  EXPECT_NEAR(r.voltage_v, 3.28f, 0.05f);
}

}  // namespace
