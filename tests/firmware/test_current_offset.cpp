// CurrentOffset alone: the sensor offset from two CV end points of the same kind, its start,
// fuse and stop conditions, the dead band and the limit, and its NVM image.
#include <gtest/gtest.h>

#include <cmath>

#include "bms/fw/estimation/current_offset.hpp"

namespace {

using Offset = bms::fw::CurrentOffset<double>;
constexpr double kDt = 0.2;

Offset::Config on() {
  Offset::Config c;
  c.enabled = true;
  c.dt_s = kDt;
  return c;
}

// One cycle between two CV-charge end points: a discharge and a charge of equal true charge (the
// cell returns to the same state), measured with `offset_a`; a CV phase ends it at `v_end`.
// Returns whether the end point fused a span.
bool cycle(Offset& o, double offset_a, double v_end, double hours = 1.0) {
  const int ticks = static_cast<int>(hours * 3600.0 / kDt);
  for (int k = 0; k < ticks; ++k) {
    o.count(2.5 + offset_a, 0u, false, false);
    o.follow_phase(false, false, 3.0, 2.5 + offset_a);
  }
  for (int k = 0; k < ticks; ++k) {
    o.count(-2.5 + offset_a, 0u, false, false);
    o.follow_phase(false, true, 3.4, -2.5 + offset_a);
  }
  o.count(-0.5 + offset_a, 0u, false, false);
  EXPECT_FALSE(o.follow_phase(true, true, v_end, -0.5 + offset_a)) << "above the end current";
  o.count(0.5 + offset_a, 0u, false, false);  // the CV current tapers; the two samples cancel
  return o.follow_phase(true, true, v_end, 0.2 + offset_a);
}

TEST(CurrentOffset, OffCorrectsNothing) {
  Offset o(Offset::Config{});
  cycle(o, 0.01, 3.6);
  EXPECT_FALSE(cycle(o, 0.01, 3.6));
  EXPECT_EQ(o.corrected(1.234), 1.234);
  EXPECT_EQ(o.fused(), 0u);
}

TEST(CurrentOffset, TwoEndPointsOfOneKindMeasureTheOffset) {
  Offset o(on());
  EXPECT_FALSE(cycle(o, 0.010, 3.6)) << "the first end point only anchors";
  EXPECT_EQ(o.offset_a(), 0.0);
  ASSERT_TRUE(cycle(o, 0.010, 3.6));
  EXPECT_NEAR(o.offset_a(), 0.010, 1e-9);
  EXPECT_NEAR(o.corrected(-2.49), -2.5, 1e-9);
  ASSERT_TRUE(cycle(o, 0.014, 3.6));
  EXPECT_NEAR(o.offset_a(), 0.012, 1e-9) << "the running mean of the spans";
}

TEST(CurrentOffset, OtherVoltageOrShortSpanIsNotTheSameState) {
  Offset o(on());
  cycle(o, 0.01, 3.6);
  EXPECT_FALSE(cycle(o, 0.01, 3.61)) << "another CV voltage";
  EXPECT_FALSE(cycle(o, 0.01, 3.61, 0.1)) << "a span under min_span_s";
  EXPECT_EQ(o.fused(), 0u);
}

TEST(CurrentOffset, DischargeEndPointsAreTheirOwnKind) {
  Offset o(on());
  auto end_discharge = [&o](double offset_a) {
    for (int k = 0; k < 36000; ++k) o.count(offset_a, 0u, false, false);  // 2 h at true zero current
    o.follow_phase(false, false, 3.0, offset_a);
    o.count(0.1 + offset_a, 0u, false, false);
    o.count(-0.1 + offset_a, 0u, false, false);
    return o.follow_phase(true, false, 2.0, 0.1 + offset_a);
  };
  EXPECT_FALSE(end_discharge(-0.02));
  ASSERT_TRUE(end_discharge(-0.02));
  EXPECT_NEAR(o.offset_a(), -0.02, 1e-9);
}

TEST(CurrentOffset, BeyondTheLimitIsNotAnOffsetAndWithinTheDeadBandIsNotCorrected) {
  Offset big(on());
  cycle(big, 0.2, 3.6);
  EXPECT_FALSE(cycle(big, 0.2, 3.6));
  EXPECT_EQ(big.offset_a(), 0.0);
  Offset small(on());
  cycle(small, 0.0001, 3.6);
  ASSERT_TRUE(cycle(small, 0.0001, 3.6));
  EXPECT_NEAR(small.measured_offset_a(), 0.0001, 1e-9);
  EXPECT_EQ(small.offset_a(), 0.0) << "inside the dead band";
  EXPECT_EQ(small.corrected(1.0), 1.0);
}

TEST(CurrentOffset, MissedTicksAreCountedAndAPowerCycleDropsTheSpans) {
  Offset o(on());
  cycle(o, 0.01, 3.6);
  o.count(0.01, 0u, false, false);
  o.count(0.01, 999u, false, false);  // 1000 ticks at the offset alone
  EXPECT_TRUE(cycle(o, 0.01, 3.6));
  EXPECT_NEAR(o.offset_a(), 0.01, 1e-9);
  o.count(0.0, 50000u, false, true);
  EXPECT_FALSE(cycle(o, 0.02, 3.6)) << "no anchor survives a power cycle";
  EXPECT_NEAR(o.offset_a(), 0.01, 1e-9) << "the offset does";
}

TEST(CurrentOffset, ImageRoundTripsAndAnOffsetBeyondTheLimitIsRefused) {
  Offset o(on());
  cycle(o, 0.01, 3.6);
  cycle(o, 0.01, 3.6);
  o.count(2.5, 0u, false, false);
  const Offset::State s = o.save();
  Offset r(on());
  ASSERT_TRUE(r.restore(s));
  EXPECT_TRUE(cycle(r, 0.01, 3.6) == cycle(o, 0.01, 3.6));
  EXPECT_EQ(r.offset_a(), o.offset_a());
  Offset::State bad = s;
  bad.offset_a = 0.5;
  EXPECT_FALSE(r.restore(bad));
  bad = s;
  bad.span_s[1] = -1.0;
  EXPECT_FALSE(r.restore(bad));
  bad = s;
  bad.flags = 8u;
  EXPECT_FALSE(r.restore(bad));
}

}  // namespace
