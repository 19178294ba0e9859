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
