// StateResync alone: the power-up and CV-end windows' start, continue and stop conditions.
#include <gtest/gtest.h>

#include <cmath>

#include "bms/fw/estimation/state_resync.hpp"

namespace {

using Resync = bms::fw::StateResync<double>;

Resync::Config observer(std::uint32_t window_ticks) {
  Resync::Config c;
  c.at_start = true;
  c.at_cv_end = true;
  c.current_a = 0.25;
  c.window_ticks = window_ticks;
  return c;
}

TEST(StateResync, OffStartsNothing) {
  Resync r(Resync::Config{});
  EXPECT_FALSE(r.should_start_at_power_up(true));
  EXPECT_FALSE(r.should_start_at_cv_end(true, 0.0));
  r.follow_phase(true, 0.0);
  EXPECT_FALSE(r.should_continue());
}

TEST(StateResync, PowerUpWindowFillsAndFitsAStraightLine) {
  Resync r(observer(3u));
  EXPECT_FALSE(r.should_start_at_power_up(false));
  ASSERT_TRUE(r.should_start_at_power_up(true));
  r.start_at_power_up();
  Resync::Fit fit{};
  r.follow_phase(false, -2.5);  // the power-up window survives a current-driven phase
  EXPECT_TRUE(r.should_continue());
  EXPECT_FALSE(r.collect(3.70, -2.5, fit));
  EXPECT_FALSE(r.collect(3.71, -2.4, fit));
  ASSERT_TRUE(r.collect(3.72, -2.3, fit));
  EXPECT_NEAR(fit.voltage_v, 3.72, 1e-12);
  EXPECT_NEAR(fit.current_a, -2.3, 1e-12);
  EXPECT_FALSE(r.should_continue()) << "closed once full";
}

// The power-up window under a current waits settle_s (the first seconds' transients); at rest,
// or with settle_s 0, it opens at the first sample; a later sample starts none.
TEST(StateResync, PowerUpUnderACurrentWaitsForTheTransientsToPass) {
  Resync::Config c = observer(3u);
  c.settle_s = 0.9;
  Resync loaded(c);
  loaded.follow_power_up(true, 2.0, 0.2);
  EXPECT_FALSE(loaded.should_continue()) << "under 2 A: pending";
  for (int k = 0; k < 3; ++k) loaded.follow_power_up(false, k == 1 ? 0.0 : 2.0, 0.2);
  EXPECT_FALSE(loaded.should_continue()) << "0.8 s of the 0.9 s (a zero crossing is not rest)";
  loaded.follow_power_up(false, 2.0, 0.2);
  EXPECT_TRUE(loaded.should_continue()) << "0.9 s under the current: the window opens";
  EXPECT_TRUE(loaded.power_up_window());
  Resync resting(c);
  resting.follow_power_up(true, 0.1, 0.2);
  EXPECT_TRUE(resting.should_continue()) << "at rest: at once";
  c.settle_s = 0.0;
  Resync at_once(c);
  at_once.follow_power_up(true, 2.0, 0.2);
  EXPECT_TRUE(at_once.should_continue()) << "settle_s 0: the first sample, as before";
  Resync later(c);
  later.follow_power_up(false, 0.0, 0.2);
  EXPECT_FALSE(later.should_continue()) << "no power-up: nothing";
  c.at_start = false;
  Resync off(c);
  off.follow_power_up(true, 0.0, 0.2);
  EXPECT_FALSE(off.should_continue());
}

TEST(StateResync, CvEndStartsOncePerPhaseWhenTheCurrentHasFallen) {
  Resync r(observer(2u));
  EXPECT_FALSE(r.should_start_at_cv_end(true, -0.5)) << "current still above the trigger";
  EXPECT_FALSE(r.should_start_at_cv_end(false, 0.0)) << "current-driven";
  r.follow_phase(true, -0.5);
  EXPECT_FALSE(r.should_continue());
  r.follow_phase(true, -0.2);
  ASSERT_TRUE(r.should_continue());
  Resync::Fit fit{};
  EXPECT_FALSE(r.collect(4.2, -0.2, fit));
  ASSERT_TRUE(r.collect(4.2, -0.19, fit));
  EXPECT_TRUE(r.succeeded(0.0, 1e-3) == false);
  EXPECT_EQ(r.count(), 1u);
  r.follow_phase(true, -0.1);
  EXPECT_FALSE(r.should_continue()) << "once per CV phase";
  r.follow_phase(false, 2.5);  // stop: the phase ended
  r.follow_phase(true, -0.1);
  EXPECT_TRUE(r.should_continue()) << "the next CV phase starts again";
}

TEST(StateResync, LeavingCvDropsAnUnfilledCvWindow) {
  Resync r(observer(50u));
  r.follow_phase(true, -0.1);
  ASSERT_TRUE(r.should_continue());
  Resync::Fit fit{};
  EXPECT_FALSE(r.collect(4.2, -0.1, fit));
  EXPECT_TRUE(r.should_stop(false));
  r.follow_phase(false, 1.0);
  EXPECT_FALSE(r.should_continue());
  EXPECT_FALSE(r.collect(4.2, -0.1, fit));
}

TEST(StateResync, SucceededSaysWhenTheInventoryMoved) {
  Resync r(observer(1u));
  EXPECT_FALSE(r.succeeded(5e-4, 1e-3));
  EXPECT_TRUE(r.succeeded(2e-3, 1e-3));
  EXPECT_EQ(r.inventory_deviation_model(), 2e-3);
  EXPECT_FALSE(r.succeeded(2.5e-3, 1e-3));
  EXPECT_EQ(r.count(), 3u);
}

TEST(StateResync, SaveRestoreRoundTripsAndChecksRanges) {
  Resync a(observer(4u));
  a.start_at_power_up();
  Resync::Fit fit{};
  a.collect(3.7, -1.0, fit);
  a.succeeded(0.01, 1e-3);
  const Resync::State good = a.save();
  Resync b(observer(4u));
  ASSERT_TRUE(b.restore(good, 0.05));
  EXPECT_EQ(b.count(), 1u);
  EXPECT_TRUE(b.should_continue());
  b.follow_phase(false, 1.0);
  EXPECT_TRUE(b.should_continue()) << "still the power-up window";
  EXPECT_FALSE(b.restore(good, 0.005)) << "inventory deviation beyond the limit";
  Resync::State bad = good;
  bad.flags = 4u;
  EXPECT_FALSE(b.restore(bad, 0.05));
  bad = good;
  bad.window.sum_v = std::nan("");
  EXPECT_FALSE(b.restore(bad, 0.05));
}

}  // namespace
