// The cost of a re-synchronisation, failing or converged: bounded, so the tick that runs it stays
// inside the board's instruction budget (docs/results/target.md "Per cell").
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "bms/fw/config/cell_choice.hpp"
#include "bms/fw/model/reduced_cell.hpp"

namespace {

using Cell = bms::fw::AboutenergyCell;
using Model = bms::fw::ReducedCell<double, Cell::Traits, Cell::Mesh>;
using ModelF = bms::fw::ReducedCell<float, Cell::Traits, Cell::Mesh>;
constexpr double kFilm = Cell::Traits::kInitialFilmOhmM2;

// The board replay's power-up window (target/data/aboutenergy_cccv_cycle1.csv.gz, tick 49): the
// model starts at the cell's initial state, 50 ticks of 0.2 s at 2 A (1C) discharge, and the
// measured voltage lies 11.4 mV below the model's at its own inventory. On the LFP plateau the
// model's voltage rises as lithium leaves the anode there, so no state near the present one
// matches; the regula falsi over the whole admissible range spent its cap of 40 evaluations
// (about 400 000 instructions on the Cortex-M7) and still failed.
template <typename M, typename S>
void expect_cheap_failure() {
  M m;
  m.init_default();
  for (int k = 0; k < 50; ++k) m.step_current(S(2.0), S(kFilm), S(0.2));
  const auto before = m.state();
  const S target_v = m.peek_voltage(S(2.0), S(kFilm), S(0.2)) - S(0.0114);
  EXPECT_FALSE(m.resync(target_v, S(2.0), S(kFilm), S(0.2), m.solid_inventory_mol()));
  // Bound: the present state and the bracket search's steps, 1 + kResyncBracketSteps = 7; the
  // search gives up at its first step against the premise (here the first).
  EXPECT_LE(m.resync_evaluations(), M::kResyncNotMonotoneEvaluations);
  EXPECT_EQ(M::kResyncNotMonotoneEvaluations, 7);
  EXPECT_LT(m.resync_evaluations(), M::kResyncIterations);
  const auto after = m.state();
  EXPECT_EQ(std::memcmp(&before, &after, sizeof(before)), 0);  // fails safe: the state unchanged
}

TEST(ResyncCost, FailingPowerUpResyncOnTheLfpPlateauIsBoundedDouble) { expect_cheap_failure<Model, double>(); }
TEST(ResyncCost, FailingPowerUpResyncOnTheLfpPlateauIsBoundedFloat) { expect_cheap_failure<ModelF, float>(); }

// A re-synchronisation the method can do on the same cell still succeeds: after the same
// discharge, the model's own voltage 2 mV lower at rest current.
TEST(ResyncCost, ReachableTargetOnTheSameCellStillConverges) {
  Model m;
  m.init_default();
  for (int k = 0; k < 50; ++k) m.step_current(2.0, kFilm, 0.2);
  const double v0 = m.peek_voltage(0.0, kFilm, 0.2);
  ASSERT_TRUE(m.resync(v0 + 2e-3, 0.0, kFilm, 0.2, m.solid_inventory_mol()));
  EXPECT_NEAR(m.peek_voltage(0.0, kFilm, 0.2), v0 + 2e-3, 1e-4);
  EXPECT_LE(m.resync_evaluations(), Model::kResyncIterations);
}

// The board's resync_probe (target/replay_tick.cpp) on About:Energy at the model's initial state:
// 5 mV above the model's voltage at 0.2 A with 0.5 % more lithium. The bracket search's third
// point lands where a cathode shell nears its limit (+273 V against -0.22 V, the root a fifth of
// the way across); the regula falsi's Illinois step halved that end once per evaluation: 18
// evaluations in double, 17 in float. Bisecting while an end is beyond kResyncFarEndV: 12 in
// both; with Anderson-Bjorck's factor after it: 11 in double, 10 in float. Bound 11: with the two
// of the inventory direction (about 11 900 instructions each on the Cortex-M4F) and the cell's
// worst tick (131 300) the tick stays below 300 000 with a margin.
template <typename M, typename S>
void expect_cheap_probe() {
  const S film = S(kFilm), dt = S(0.2), current = S(0.2);
  M m;
  m.init_default();
  const S target_v = m.peek_voltage(current, film, dt) + S(0.005);
  const S inventory = m.solid_inventory_mol() * S(1.005);
  ASSERT_TRUE(m.resync(target_v, current, film, dt, inventory));
  EXPECT_LE(m.resync_evaluations(), 11);
  // What it solves is unchanged: the voltage within the regula falsi's tolerance, the inventory held.
  EXPECT_LT(std::fabs(m.peek_voltage(current, film, dt) - target_v), S(M::kResyncToleranceV));
  EXPECT_NEAR(m.solid_inventory_mol() / inventory, S(1), S(sizeof(S) >= sizeof(double) ? 1e-12 : 1e-5));
}

TEST(ResyncCost, ConvergedProbeOnAboutEnergyIsCheapDouble) { expect_cheap_probe<Model, double>(); }
TEST(ResyncCost, ConvergedProbeOnAboutEnergyIsCheapFloat) { expect_cheap_probe<ModelF, float>(); }

}  // namespace
