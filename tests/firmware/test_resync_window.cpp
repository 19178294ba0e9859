// ResyncWindow: the straight-line fit a state re-synchronisation matches.
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include "bms/fw/estimation/resync_window.hpp"

namespace {

using Window = bms::fw::ResyncWindow<double>;

TEST(ResyncWindow, ALineIsRecoveredAtItsLastSample) {
  Window w;
  w.open(50);
  for (int k = 0; k < 50; ++k) w.add(3.6 + 1e-5 * k, -0.25 + 3e-3 * 0.2 * k);
  ASSERT_TRUE(w.full());
  const auto f = w.fit();
  EXPECT_NEAR(f.voltage_v, 3.6 + 1e-5 * 49, 1e-12);
  EXPECT_NEAR(f.current_a, -0.25 + 3e-3 * 0.2 * 49, 1e-12);
}

TEST(ResyncWindow, OneSampleIsThatSampleAndAFullWindowTakesNoMore) {
  Window w;
  w.open(1);
  w.add(3.5, 0.1);
  w.add(9.0, 9.0);  // ignored: the window is full
  EXPECT_EQ(w.fit().voltage_v, 3.5);
  EXPECT_EQ(w.fit().current_a, 0.1);
  w.close();
  EXPECT_FALSE(w.is_open());
}

// The point of the window: noise on the matched measurement falls from sigma to about
// 2 sigma / sqrt(n) (the variance of a line's end point), 0.28 sigma for n = 50.
TEST(ResyncWindow, NoiseOnTheMatchedValueShrinks) {
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.2e-3);
  double sum_sq_one = 0.0, sum_sq_fit = 0.0;
  const int trials = 400;
  for (int t = 0; t < trials; ++t) {
    Window w;
    w.open(50);
    double last_noise = 0.0;
    for (int k = 0; k < 50; ++k) {
      last_noise = noise(rng);
      w.add(3.6 + last_noise, 0.2);
    }
    sum_sq_one += last_noise * last_noise;
    sum_sq_fit += std::pow(w.fit().voltage_v - 3.6, 2);
  }
  const double rms_one = std::sqrt(sum_sq_one / trials), rms_fit = std::sqrt(sum_sq_fit / trials);
  EXPECT_NEAR(rms_one, 0.2e-3, 0.03e-3);
  EXPECT_LT(rms_fit, 0.4 * rms_one);
}

TEST(ResyncWindow, RestoreRefusesAnInconsistentImage) {
  Window w;
  w.open(10);
  w.add(3.0, 1.0);
  Window::State s = w.state();
  Window other;
  ASSERT_TRUE(other.restore(s));
  EXPECT_EQ(other.fit().voltage_v, 3.0);
  s.samples = 11;  // more samples than the window holds
  EXPECT_FALSE(other.restore(s));
  s = w.state();
  s.sum_v = NAN;
  EXPECT_FALSE(other.restore(s));
}

}  // namespace
