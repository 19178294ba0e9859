// FilmLevel alone: the held, averaged and growth-propagated film of RCSI's path.
#include <gtest/gtest.h>

#include <cmath>

#include "bms/fw/estimation/film_level.hpp"

namespace {

using Film = bms::fw::FilmLevel<double>;

TEST(FilmLevel, HeldByDefault) {
  Film f(Film::Config{}, 1e-3);
  f.add_growth(-1e5, 0.2);
  EXPECT_EQ(f.value_ohm_m2(), 1e-3) << "no growth factor: held";
  f.record(2e-3);
  f.record(4e-3);
  EXPECT_EQ(f.value_ohm_m2(), 4e-3) << "the last value";
}

TEST(FilmLevel, AveragesOverTheWindowAndRestartsAtACharge) {
  Film::Config c;
  c.average = true;
  Film f(c, 1e-3);
  f.record(2e-3);
  f.record(4e-3);
  EXPECT_DOUBLE_EQ(f.value_ohm_m2(), 3e-3);
  EXPECT_DOUBLE_EQ(f.begin_charge(), 3e-3);
  f.record(6e-3);
  EXPECT_DOUBLE_EQ(f.value_ohm_m2(), 6e-3) << "the previous charge's samples are gone";
}

TEST(FilmLevel, GrowthFollowsTheSideCurrentAndIsFoldedAtACharge) {
  Film::Config c;
  c.growth_ohm_m2_per_a_m3_s = 1e-9;
  Film f(c, 1e-3);
  f.add_growth(-1000.0, 0.2);  // side current is negative: the film grows
  EXPECT_DOUBLE_EQ(f.growth_ohm_m2(), 2e-7);
  EXPECT_DOUBLE_EQ(f.value_ohm_m2(), 1e-3 + 2e-7);
  EXPECT_DOUBLE_EQ(f.begin_charge(), 1e-3 + 2e-7);
  EXPECT_EQ(f.growth_ohm_m2(), 0.0);
}

TEST(FilmLevel, RestoreChecksRanges) {
  Film a(Film::Config{}, 1e-3);
  a.record(2e-3);
  const Film::State good = a.save();
  Film b(Film::Config{}, 0.0);
  ASSERT_TRUE(b.restore(good, 0.0, 1.0));
  EXPECT_EQ(b.value_ohm_m2(), 2e-3);
  Film::State bad = good;
  bad.r_held_ohm_m2 = 1e200;
  EXPECT_FALSE(b.restore(bad, 0.0, 1.0));
  bad = good;
  bad.growth_ohm_m2 = std::nan("");
  EXPECT_FALSE(b.restore(bad, 0.0, 1.0));
  bad = good;
  bad.avg_sum_ohm_m2 = 5.0;  // no samples: within one span of 0 only
  EXPECT_FALSE(b.restore(bad, 0.0, 1.0));
  bad = good;
  bad.reserved = 1u;
  EXPECT_FALSE(b.restore(bad, 0.0, 1.0));
}

}  // namespace
