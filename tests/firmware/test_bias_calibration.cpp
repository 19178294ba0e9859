// BiasCalibration alone: the reference charge's start, continue and stop conditions.
#include <gtest/gtest.h>

#include <cmath>

#include "bms/fw/estimation/bias_calibration.hpp"

namespace {

using Bias = bms::fw::BiasCalibration<double>;

Bias::Config enabled(std::uint32_t after_resyncs) {
  Bias::Config c;
  c.enabled = true;
  c.after_resyncs = after_resyncs;
  c.dt_s = 0.2;
  return c;
}

TEST(BiasCalibration, DisabledNeverCollectsNorBlocks) {
  Bias b(Bias::Config{});
  EXPECT_FALSE(b.should_collect(true, true, 10u));
  EXPECT_FALSE(b.blocks_learning());
  b.collect(1e-3);
  b.stop_at_charge_end();
  EXPECT_FALSE(b.calibrated());
  EXPECT_EQ(b.corrected(2e-3), 2e-3);
}

TEST(BiasCalibration, CollectsInAWarmCcChargeAfterEnoughResyncs) {
  Bias b(enabled(1u));
  EXPECT_TRUE(b.blocks_learning());
  EXPECT_FALSE(b.should_collect(true, true, 0u)) << "waits for a re-synchronisation";
  EXPECT_FALSE(b.should_collect(false, true, 1u)) << "not in CC charge";
  EXPECT_FALSE(b.should_collect(true, false, 1u)) << "in the warm-up";
  EXPECT_TRUE(b.should_collect(true, true, 1u));
}

TEST(BiasCalibration, StopsWithTheMeanOfALongEnoughReferenceCharge) {
  Bias b(enabled(0u));
  for (int k = 0; k < 300; ++k) b.collect(k % 2 == 0 ? 1e-3 : 3e-3);  // 60 s at 0.2 s
  ASSERT_TRUE(b.long_enough());
  b.stop_at_charge_end();
  ASSERT_TRUE(b.calibrated());
  EXPECT_NEAR(b.bias_v(), 2e-3, 1e-15);
  EXPECT_FALSE(b.blocks_learning());
  EXPECT_FALSE(b.should_collect(true, true, 5u)) << "calibrated once";
  EXPECT_NEAR(b.corrected(5e-3), 3e-3, 1e-15);
}

TEST(BiasCalibration, AShortChargeIsDroppedAndTheNextIsTheReference) {
  Bias b(enabled(0u));
  for (int k = 0; k < 299; ++k) b.collect(1.0);  // 59.8 s
  EXPECT_FALSE(b.long_enough());
  b.stop_at_charge_end();
  EXPECT_FALSE(b.calibrated());
  EXPECT_EQ(b.save().samples, 0u);
  EXPECT_EQ(b.save().sum_v, 0.0);
  for (int k = 0; k < 300; ++k) b.collect(-4e-4);
  b.stop_at_charge_end();
  ASSERT_TRUE(b.calibrated());
  EXPECT_NEAR(b.bias_v(), -4e-4, 1e-15) << "nothing of the short charge";
}

TEST(BiasCalibration, RestoreChecksRanges) {
  Bias a(enabled(0u));
  for (int k = 0; k < 10; ++k) a.collect(2e-3);
  const Bias::State good = a.save();
  Bias b(enabled(0u));
  ASSERT_TRUE(b.restore(good));
  EXPECT_EQ(b.save().samples, 10u);
  Bias::State bad = good;
  bad.bias_v = 5.0;
  EXPECT_FALSE(b.restore(bad));
  bad = good;
  bad.sum_v = 11.0;  // more than 1 V per sample
  EXPECT_FALSE(b.restore(bad));
  bad = good;
  bad.sum_v = std::nan("");
  EXPECT_FALSE(b.restore(bad));
  bad = good;
  bad.calibrated = 2u;
  EXPECT_FALSE(b.restore(bad));
}

}  // namespace
