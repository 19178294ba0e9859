// Reset, history reset and save/restore of the RCSI estimator state.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <type_traits>

#include <Eigen/Core>

#include <bms/fw/estimation/fw_status.hpp>
#include <bms/fw/estimation/rcsi_estimator.hpp>
#include "../common/rcsi_test_config.hpp"

namespace {

using bms::fw::FwStatus;
using bms::fw::has_status;

using Estimator = bms::fw::RcsiEstimator<double, 2, 1>;

static_assert(std::is_trivially_copyable<Estimator::State>::value, "State is saved as bytes");

Estimator::Config paper_like_config() {
  Estimator::Config c = bms::test::rcsi_test_config<Estimator>();
  c.p0_y0 = 1e-12;
  return c;
}

// Deterministic pseudo-measurements: small voltage errors and a J_s around -10 A/m3.
struct Drive {
  std::mt19937 rng{99u};
  std::normal_distribution<double> normal{0.0, 1.0};
  void tick(Estimator& est) {
    est.predict();
    est.update(1e-5 * normal(rng), -10.0 + normal(rng));
  }
};

bool same_bytes(const Estimator::State& a, const Estimator::State& b) {
  return std::memcmp(&a, &b, sizeof(Estimator::State)) == 0;
}

TEST(RcsiState, ResetRestoresTheta0AndP0AndKeepsHistory) {
  const auto config = paper_like_config();
  Estimator est(config);
  const Estimator::Vector theta0 = est.theta();
  const Estimator::Matrix p0 = est.p();
  EXPECT_EQ(theta0, config.theta0);
  Estimator::Vector p0_diag;
  p0_diag << 5e-7, 5e-7, 1e-12, 1e-12;
  EXPECT_EQ(p0, Estimator::Matrix(p0_diag.asDiagonal()));

  Drive drive;
  for (int k = 0; k < 50; ++k) {
    drive.tick(est);
  }
  ASSERT_NE(est.theta(), theta0);
  ASSERT_NE(est.p(), p0);
  const Estimator::Vector history = est.regressor();
  const double u_hat = est.u_hat_ohm_m2();
  const bms::fw::StatusWord status = est.status();

  est.reset();
  EXPECT_EQ(est.theta(), theta0);  // bit-exact
  EXPECT_EQ(est.p(), p0);
  EXPECT_EQ(est.regressor(), history);  // the film resistance is continuous across cycles
  EXPECT_EQ(est.u_hat_ohm_m2(), u_hat);
  EXPECT_EQ(est.status(), status);
  // Learning continues at once after reset() (no warm-up: the history is real).
  est.predict();
  est.update(1e-4, -10.0);
  EXPECT_NE(est.theta(), theta0);
}

TEST(RcsiState, ResetHistoryRestartsSignalsAndDelaysLearning) {
  Estimator est(paper_like_config());
  Drive drive;
  for (int k = 0; k < 20; ++k) {
    drive.tick(est);
  }
  EXPECT_TRUE(est.reset_history(5e-3, -8.0));
  Estimator::Vector expected;
  expected << 5e-3, 5e-3, -8.0, -8.0;
  EXPECT_EQ(est.regressor(), expected);
  // D = 1: the first tick after the history reset has no u_hat(k-1) from predict(): no learning.
  const Estimator::Vector theta = est.theta();
  est.predict();
  est.update(1e-3, -10.0);
  EXPECT_EQ(est.theta(), theta);
  EXPECT_TRUE(std::isnan(est.u_star_ohm_m2()));
  EXPECT_FALSE(est.theta_updated());
  est.predict();
  est.update(1e-3, -10.0);
  EXPECT_NE(est.theta(), theta);
  EXPECT_FALSE(std::isnan(est.u_star_ohm_m2()));
  EXPECT_TRUE(est.theta_updated());
  // Invalid history values are rejected and flagged.
  const Estimator::Vector before = est.regressor();
  EXPECT_FALSE(est.reset_history(std::nan(""), -8.0));
  EXPECT_FALSE(est.reset_history(10.0, -8.0));  // above r_film_max
  EXPECT_EQ(est.regressor(), before);
  EXPECT_TRUE(has_status(est.status(), FwStatus::kConfigInvalid));
}

TEST(RcsiState, SaveRestoreRoundTripsBitExactly) {
  const auto config = paper_like_config();
  Estimator a(config);
  Drive drive_a;
  for (int k = 0; k < 137; ++k) {
    drive_a.tick(a);
  }
  a.set_markov_parameter(0.02);
  a.predict();  // save in the middle of a tick: the pending u_hat is part of the state
  const Estimator::State saved = a.save();
  EXPECT_EQ(saved.layout_tag, Estimator::kLayoutTag);

  // Through raw bytes, as to and from non-volatile memory.
  unsigned char nvm[sizeof(Estimator::State)];
  std::memcpy(nvm, &saved, sizeof nvm);
  Estimator::State loaded;
  std::memcpy(&loaded, nvm, sizeof loaded);

  Estimator b(config);
  ASSERT_TRUE(b.restore(loaded));
  EXPECT_TRUE(same_bytes(b.save(), saved));
  EXPECT_EQ(b.theta(), a.theta());
  EXPECT_EQ(b.p(), a.p());
  EXPECT_EQ(b.markov_parameter(), 0.02);

  // Both continue identically, bit for bit.
  a.update(2e-5, -9.5);
  b.update(2e-5, -9.5);
  Drive drive_b = drive_a;
  for (int k = 0; k < 100; ++k) {
    drive_a.tick(a);
    drive_b.tick(b);
    ASSERT_TRUE(same_bytes(a.save(), b.save())) << "k=" << k;
  }
}

TEST(RcsiState, RestoreRejectsCorruptImages) {
  const auto config = paper_like_config();
  Estimator a(config);
  Drive drive;
  for (int k = 0; k < 10; ++k) {
    drive.tick(a);
  }
  const Estimator::State good = a.save();

  Estimator b(config);
  const Estimator::State fresh = b.save();
  auto expect_rejected = [&](const Estimator::State& bad, const char* what) {
    b.clear_status();
    EXPECT_FALSE(b.restore(bad)) << what;
    Estimator::State now = b.save();
    EXPECT_TRUE(has_status(now.status, FwStatus::kConfigInvalid)) << what;
    now.status = fresh.status;
    now.tick_status = fresh.tick_status;
    EXPECT_TRUE(same_bytes(now, fresh)) << what << ": a rejected restore must change nothing";
  };

  Estimator::State bad = good;
  bad.layout_tag ^= 1u;
  expect_rejected(bad, "layout tag");
  bad = good;
  bad.rls.theta[1] = std::nan("");
  expect_rejected(bad, "NaN theta");
  bad = good;
  bad.rls.p[1] += 1e-9;  // P(1,0) != P(0,1)
  expect_rejected(bad, "asymmetric P");
  bad = good;
  bad.rls.p[0] = -1.0;
  expect_rejected(bad, "negative P diagonal");
  bad = good;
  bad.phi_history[0] = 1.0;  // u_hat(k-1) above r_film_max
  expect_rejected(bad, "history out of range");
  bad = good;
  bad.markov_v_per_ohm_m2 = 0.0;
  expect_rejected(bad, "H = 0");
  bad = good;
  bad.flags = 0x80u;
  expect_rejected(bad, "unknown flags");

  EXPECT_TRUE(b.restore(good));
}

TEST(RcsiState, FloatStateRoundTrips) {
  using EstimatorF = bms::fw::RcsiEstimator<float, 1, 1>;
  EstimatorF::Config c;
  c.theta0 << 1.0f, 0.0f;
  c.r_film_init_ohm_m2 = 3.4e-3f;
  c.j_side_init_a_m3 = -10.0f;
  EstimatorF a(c);
  for (int k = 0; k < 20; ++k) {
    a.predict();
    a.update(1e-4f * static_cast<float>(k % 3), -10.0f);
  }
  EstimatorF b(c);
  ASSERT_TRUE(b.restore(a.save()));
  const EstimatorF::State sa = a.save();
  const EstimatorF::State sb = b.save();
  EXPECT_EQ(std::memcmp(&sa, &sb, sizeof sa), 0);
}

}  // namespace
