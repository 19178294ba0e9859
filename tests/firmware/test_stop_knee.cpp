// The stop condition of a charge's learning from the reduced model's own OCV slope
// (IdentifierFilmPath::Config::stop_knee_*): where the probed inventory sensitivity S = dV/dnu
// rises steeply (a flat-OCP cell's end-of-charge knee, where the model's misfit is tens of mV and
// the fit absorbs it as film), the rest of that charge is not learned from; the next charge learns
// again. Off by default: the path then follows the knee's data, as before the option existed.
#include <gtest/gtest.h>

#include <cmath>

#include "bms/fw/estimation/identifier_film_path.hpp"
#include "film_path_learning.hpp"

namespace {

namespace fw = bms::fw;
using Path = fw::IdentifierFilmPath<double>;

constexpr double kFilmOhmM2 = 3.391e-3;
// About:Energy's LFP: on the plateau S is -1 to -2 mV per 1 % of inventory, in the knee it rises to
// -90 ... -530 mV per 1 % while the model's misfit grows to tens of mV.
constexpr double kPlateauStartSlopeV = -0.2, kPlateauEndSlopeV = -0.1, kKneeEndSlopeV = -20.0;
constexpr double kKneeEndMisfitV = -0.02;
// Its measured voltage rises 0.05 mV/s on the plateau and 1.3 mV/s in the knee.
constexpr double kPlateauRiseVPerS = 5e-5, kKneeRiseVPerS = 1.3e-3;
struct NoSpreadModel {};

Path::Config path_config(double ratio, bool inventory_sd, double rise = 0.0) {
  Path::Config c;
  c.identifier.r_film_nominal_ohm_m2 = kFilmOhmM2;
  c.identifier.growth_nominal_ohm_m2_per_a_m3_s = 1e-12;
  c.temperature_sd_k = 0.0;
  c.stop_knee_slope_ratio = ratio;
  c.stop_knee_inventory_sd = inventory_sd;
  c.stop_knee_rise_ratio = rise;
  return c;
}

// One charge: `bulk` ticks on the plateau (S flattening, so film and inventory are told apart)
// whose data imply film `film_ohm_m2`, then `knee` ticks where S steepens linearly and the model's
// misfit grows as the square of the knee's fraction (not in proportion to S, so neither the
// inventory nor the film explains it). Returns the status of the last tick.
fw::StatusWord charge(Path& path, int bulk, double film_ohm_m2, int knee) {
  fw::LearningGate<double> gate(fw::LearningGate<double>::Config{});
  const fw::StateResync<double> resync(fw::StateResync<double>::Config{});
  fw::StatusWord last = 0u;
  double v = 3.3;
  for (int k = 0; k < bulk + knee; ++k) {
    const bool in_knee = k >= bulk;
    const double f = in_knee ? double(k - bulk) / knee : double(k) / bulk;
    const double s_v = in_knee ? kPlateauEndSlopeV + (kKneeEndSlopeV - kPlateauEndSlopeV) * f
                               : kPlateauStartSlopeV + (kPlateauEndSlopeV - kPlateauStartSlopeV) * f;
    v += (in_knee ? kKneeRiseVPerS : kPlateauRiseVPerS) * fw::test::kPathDtS;
    fw::FilmTick<double> t{};
    t.r = fw::ModelTickResult<double>{v, fw::test::kPathChargeA, -1.0, fw::test::kPathH, 0, true, true};
    t.current_a = fw::test::kPathChargeA;
    t.u_ohm_m2 = path.film_in_use(true);
    t.z_v = fw::test::kPathH * (t.u_ohm_m2 - film_ohm_m2) + (in_knee ? kKneeEndMisfitV * f * f : 0.0);
    t.v_probe_v = t.r.voltage_v + 1e-3 * s_v;
    t.dt_s = fw::test::kPathDtS;
    t.open = true;
    t.probed = true;
    last = path.learn(t, NoSpreadModel{}, gate, resync).status;
  }
  return last;
}

void expect_stops_in_the_knee(double ratio, bool inventory_sd, double rise = 0.0) {
  const double bulk = 1.1 * kFilmOhmM2;
  const double bound = 0.006 * bulk;  // the stated model bound, film_model_sd_rel

  Path off(path_config(0.0, false), fw::test::kPathDtS);
  charge(off, 2000, bulk, 1000);
  EXPECT_GT(std::fabs(off.r_film_ohm_m2() - bulk), 5.0 * bound) << "off (the default): the knee is learned";

  Path on(path_config(ratio, inventory_sd, rise), fw::test::kPathDtS);
  const fw::StatusWord st = charge(on, 2000, bulk, 1000);
  EXPECT_NEAR(on.r_film_ohm_m2(), bulk, bound) << "the level from before the knee is kept";
  EXPECT_NE(st & fw::bit(fw::FwStatus::kInnovationRejected), 0u) << "and the stop is reported";

  // The next charge, on the plateau alone, learns again.
  const double before = on.r_film_ohm_m2();
  charge(on, 3000, 1.2 * kFilmOhmM2, 0);
  EXPECT_GT(on.r_film_ohm_m2() - before, bound) << "a new charge learns";
}

TEST(StopKnee, TheModelsSlopeAboveKTimesTheChargesSmallestStopsTheCharge) { expect_stops_in_the_knee(10.0, false); }

TEST(StopKnee, TheSlopeTimesTheInventorySdAboveTheGateStopsTheCharge) { expect_stops_in_the_knee(0.0, true); }

TEST(StopKnee, TheMeasuredRiseAboveKTimesTheChargesMeanStopsTheCharge) { expect_stops_in_the_knee(0.0, false, 5.0); }

TEST(StopKnee, APlateauAloneNeverStops) {
  Path on(path_config(10.0, true, 5.0), fw::test::kPathDtS);
  const fw::StatusWord st = charge(on, 3000, 1.1 * kFilmOhmM2, 0);
  EXPECT_EQ(st & fw::bit(fw::FwStatus::kInnovationRejected), 0u);
  EXPECT_NEAR(on.r_film_ohm_m2(), 1.1 * kFilmOhmM2, 0.006 * kFilmOhmM2);
}

}  // namespace
