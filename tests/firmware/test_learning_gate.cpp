// LearningGate alone: when RCSI / the identifier may learn (start, continue, stop).
#include <gtest/gtest.h>

#include "bms/fw/estimation/learning_gate.hpp"

namespace {

using Gate = bms::fw::LearningGate<double>;

Gate::Config warmup_config(double warmup_s) {
  Gate::Config c;
  c.warmup_s = warmup_s;
  c.dt_s = 0.2;
  return c;
}

TEST(LearningGate, OpensOnlyInCcChargeAfterTheWarmUp) {
  Gate g(warmup_config(1.0));  // 5 ticks of warm-up
  for (int k = 1; k <= 5; ++k) {
    g.count_phase(true);
    EXPECT_FALSE(g.warm()) << k;
    EXPECT_FALSE(g.should_open(true, true)) << k;
  }
  g.count_phase(true);
  EXPECT_TRUE(g.warm());
  EXPECT_TRUE(g.should_open(true, true));
  EXPECT_FALSE(g.should_open(false, true)) << "not in CC charge";
  EXPECT_FALSE(g.should_open(true, false)) << "the bias is not known yet";
}

TEST(LearningGate, StartsOnceThenContinuesAndStartsAgainAfterAStop) {
  Gate g(warmup_config(0.0));
  g.count_phase(true);
  const bool open = g.should_open(true, true);
  ASSERT_TRUE(open);
  EXPECT_TRUE(g.should_start(open));
  g.close_tick(open);
  EXPECT_FALSE(g.should_start(true)) << "continuing, not starting";
  g.close_tick(false);  // the window closed (stop)
  EXPECT_TRUE(g.should_start(true));
  EXPECT_FALSE(g.should_start(false));
}

TEST(LearningGate, PhaseEndResetsTheWarmUp) {
  Gate g(warmup_config(0.5));
  EXPECT_FALSE(g.phase_ended(false)) << "no CC phase yet";
  for (int k = 0; k < 4; ++k) g.count_phase(true);
  ASSERT_TRUE(g.warm());
  EXPECT_TRUE(g.phase_ended(false));
  EXPECT_FALSE(g.phase_ended(true));
  g.count_phase(false);
  EXPECT_FALSE(g.warm());
  EXPECT_FALSE(g.phase_ended(false));
}

TEST(LearningGate, IdentifierLearnsOnlyWhenCurrentDrivenAndLearningOn) {
  Gate::Config c = warmup_config(0.0);
  c.identify_growth = true;
  Gate g(c);
  EXPECT_TRUE(g.should_identify(true, false));
  EXPECT_FALSE(g.should_identify(true, true)) << "voltage-driven step";
  EXPECT_FALSE(g.should_identify(false, false)) << "window closed";
  EXPECT_TRUE(g.should_start_identifying(true));
  g.identified(true);
  EXPECT_FALSE(g.should_start_identifying(true));
  g.identified(false);
  EXPECT_TRUE(g.should_start_identifying(true));
  c.learning = false;
  EXPECT_FALSE(Gate(c).should_identify(true, false)) << "control run";
  c.learning = true;
  c.identify_growth = false;
  EXPECT_FALSE(Gate(c).should_identify(true, false)) << "RCSI learns instead";
}

TEST(LearningGate, SaveRestoreRoundTripsAndRejectsUnknownFlags) {
  Gate a(warmup_config(0.0));
  for (int k = 0; k < 7; ++k) a.count_phase(true);
  a.close_tick(true);
  a.identified(true);
  Gate b(warmup_config(0.0));
  ASSERT_TRUE(b.restore(a.save()));
  EXPECT_EQ(b.save().cc_ticks, 7u);
  EXPECT_EQ(b.save().flags, 3u);
  EXPECT_FALSE(b.should_start(true));
  Gate::State bad = a.save();
  bad.flags = 4u;
  EXPECT_FALSE(b.restore(bad));
}

}  // namespace

namespace {

TEST(LearningGate, MarkovFromTheModelOnlyAtTheWindowsStartAndOnlyWhenConfigured) {
  Gate::Config c;
  Gate paper(c);
  EXPECT_FALSE(paper.should_take_markov_from_model(true)) << "the paper's constant H";
  c.markov_from_model = true;
  Gate g(c);
  EXPECT_TRUE(g.should_take_markov_from_model(true));
  EXPECT_FALSE(g.should_take_markov_from_model(false));
  g.close_tick(true);
  EXPECT_FALSE(g.should_take_markov_from_model(true)) << "continuing: H kept";
}

}  // namespace
