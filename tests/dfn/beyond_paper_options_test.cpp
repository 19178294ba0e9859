// `bmssim estimate --beyond-paper` takes its settings from the firmware's own
// BmsCore::beyond_paper_config, and an option the user gave explicitly is kept.
#include <gtest/gtest.h>

#include <cstring>

#include "bms/fw/bms_core.hpp"
#include "estimation/estimate_run.hpp"

namespace {

TEST(BeyondPaperOptions, AreTheFirmwaresBestConfig) {
  bms::EstimateOptions o;
  bms::apply_beyond_paper(o, [](const char*) { return false; });
  const auto cfg = bms::fw::BmsCore<double>::beyond_paper_config(0.0, 1.0);
  EXPECT_EQ(o.markov_from_model, cfg.markov_from_model);
  EXPECT_EQ(o.p0, cfg.estimator.p0_u);
  EXPECT_EQ(o.p0_y0, cfg.estimator.p0_y0);
  EXPECT_EQ(o.resync, cfg.resync_at_cv_end);
  EXPECT_EQ(o.resync_at_start, cfg.resync_at_start);
  EXPECT_EQ(o.resync_window_ticks, cfg.resync_window_ticks);
  EXPECT_EQ(o.warmup_s, cfg.rcsi_warmup_s);
  EXPECT_EQ(o.calibrate_bias, cfg.calibrate_bias);
  EXPECT_EQ(o.reference_after_resyncs, cfg.reference_after_resyncs);
  EXPECT_EQ(o.average_estimate, cfg.average_estimate);
  EXPECT_TRUE(o.propagate_growth);
  EXPECT_TRUE(o.resync && o.resync_window_ticks > 1u && o.warmup_s > 0.0);  // not the paper's plain settings
}

TEST(BeyondPaperOptions, ExplicitOptionsWin) {
  bms::EstimateOptions o;
  o.resync_window_ticks = 1;
  o.warmup_s = 30.0;
  o.resync_at_start = false;
  bms::apply_beyond_paper(o, [](const char* flag) {
    return std::strcmp(flag, "--resync-window") == 0 || std::strcmp(flag, "--warmup") == 0 ||
           std::strcmp(flag, "--no-start-resync") == 0;
  });
  EXPECT_EQ(o.resync_window_ticks, 1u);
  EXPECT_EQ(o.warmup_s, 30.0);
  EXPECT_FALSE(o.resync_at_start);
  EXPECT_TRUE(o.calibrate_bias);  // the rest still comes from the preset
}

}  // namespace
