// The stop condition of a charge's learning (IdentifierFilmPath::Config::stop_film_move): once the
// fit has settled in a charge, a move of its film by more than K x the stated model bound stops
// that charge's learning (a flat-OCP cell's end-of-charge knee); the next charge learns again. Off
// by default: the path then follows the moved data, as before the option existed.
#include <gtest/gtest.h>

#include <cmath>

#include "bms/fw/estimation/identifier_film_path.hpp"
#include "film_path_learning.hpp"

namespace {

namespace fw = bms::fw;
using Path = fw::IdentifierFilmPath<double>;

constexpr double kFilmOhmM2 = 3.391e-3;
struct NoSpreadModel {};

Path::Config path_config(double stop_film_move) {
  Path::Config c;
  c.identifier.r_film_nominal_ohm_m2 = kFilmOhmM2;
  c.identifier.growth_nominal_ohm_m2_per_a_m3_s = 1e-12;
  c.temperature_sd_k = 0.0;
  c.stop_film_move = stop_film_move;
  return c;
}

// One charge: `bulk` ticks whose data imply film `bulk_ohm_m2`, then `knee` ticks implying
// `knee_ohm_m2` (the model leaving the cell). Returns the status of the last tick.
fw::StatusWord charge(Path& path, int bulk, double bulk_ohm_m2, int knee, double knee_ohm_m2) {
  fw::LearningGate<double> gate(fw::LearningGate<double>::Config{});
  const fw::StateResync<double> resync(fw::StateResync<double>::Config{});
  fw::StatusWord last = 0u;
  for (int k = 0; k < bulk + knee; ++k) {
    const double truth = k < bulk ? bulk_ohm_m2 : knee_ohm_m2;
    fw::FilmTick<double> t{};
    t.r = fw::ModelTickResult<double>{3.6, fw::test::kPathChargeA, -1.0, fw::test::kPathH, 0, true, true};
    t.current_a = fw::test::kPathChargeA;
    t.u_ohm_m2 = path.film_in_use(true);
    t.z_v = fw::test::kPathH * (t.u_ohm_m2 - truth);
    t.v_probe_v = t.r.voltage_v;
    t.dt_s = fw::test::kPathDtS;
    t.open = true;
    t.probed = true;
    last = path.learn(t, NoSpreadModel{}, gate, resync).status;
  }
  return last;
}

TEST(StopFilmMove, AKneeAfterTheFitSettledIsNotLearnedFromInThatCharge) {
  const double bulk = 1.1 * kFilmOhmM2, knee = 1.2 * kFilmOhmM2;
  const double bound = 0.006 * bulk;  // the stated model bound, film_model_sd_rel

  Path off(path_config(0.0), fw::test::kPathDtS);
  charge(off, 1000, bulk, 1000, knee);
  EXPECT_GT(off.r_film_ohm_m2(), bulk + 5.0 * bound) << "off (the default): the knee is learned";

  Path on(path_config(1.0), fw::test::kPathDtS);
  const fw::StatusWord st = charge(on, 1000, bulk, 1000, knee);
  EXPECT_NEAR(on.r_film_ohm_m2(), bulk, 1.5 * bound) << "the level from before the knee is kept";
  EXPECT_NE(st & fw::bit(fw::FwStatus::kInnovationRejected), 0u) << "and the stop is reported";

  // The next charge learns again; its fit is settled from the first tick (nothing relinearised it),
  // so it too stops once its film has moved by the bound: a level that truly moves is followed one
  // bound per charge (why the LCO's first charges, still converging, fail with it on).
  const double before = on.r_film_ohm_m2();
  charge(on, 3000, knee, 0, knee);
  EXPECT_GT(on.r_film_ohm_m2() - before, 0.5 * bound) << "a new charge learns";
  EXPECT_LT(on.r_film_ohm_m2() - before, 1.5 * bound) << "until its film has moved by the bound";
}

}  // namespace
