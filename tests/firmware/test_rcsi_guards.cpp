// Guards of the RCSI estimator and its RLS core: non-finite inputs, clipping, covariance
// cap, call order, invalid configuration, and an adversarial property test.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>

#include <Eigen/Core>

#include <bms/fw/estimation/fw_status.hpp>
#include <bms/fw/estimation/rcsi_estimator.hpp>
#include <bms/fw/estimation/rls.hpp>

namespace {

using bms::fw::bit;
using bms::fw::FwStatus;
using bms::fw::has_status;
using bms::fw::StatusWord;

using Estimator = bms::fw::RcsiEstimator<double, 1, 1>;

Estimator::Config base_config() {
  Estimator::Config c;
  c.markov_v_per_ohm_m2 = 0.5;
  c.lambda = 0.98;
  c.p0_u = 1.0;
  c.p0_y0 = 1.0;
  c.p_trace_cap_factor = 10.0;
  c.theta0 << 0.5, 0.1;
  c.r_film_init_ohm_m2 = 0.2;
  c.j_side_init_a_m3 = 1.0;
  c.r_film_min_ohm_m2 = -10.0;
  c.r_film_max_ohm_m2 = 10.0;
  return c;
}

void warm_up(Estimator& est, int ticks) {
  for (int k = 0; k < ticks; ++k) {
    est.predict();
    est.update(0.01 * static_cast<double>(k % 5) - 0.02, 1.0 + 0.1 * static_cast<double>(k % 3));
  }
}

// A tick whose learning step is rejected must equal a tick without learning: theta and P
// unchanged, and time advances with u_hat(k) and y0_hat(k) (the model has used u_hat(k),
// so freezing the history would misalign the delay d). Only the status words differ.
TEST(RcsiGuards, NonFiniteZChangesNothingButStatus) {
  const double bad_values[] = {std::numeric_limits<double>::quiet_NaN(),
                               std::numeric_limits<double>::infinity(),
                               -std::numeric_limits<double>::infinity()};
  for (const double bad : bad_values) {
    Estimator a(base_config());
    warm_up(a, 10);
    Estimator b = a;
    a.predict();
    const StatusWord status = a.update(bad, 1.3);
    b.predict();
    b.advance_without_learning(1.3);
    EXPECT_EQ(status, bit(FwStatus::kRejectedNonFinite)) << bad;
    EXPECT_FALSE(a.theta_updated());
    EXPECT_TRUE(has_status(a.status(), FwStatus::kRejectedNonFinite));
    EXPECT_EQ(a.theta(), b.theta());
    EXPECT_EQ(a.p(), b.p());
    Estimator::State sa = a.save();
    Estimator::State sb = b.save();
    sa.status = sb.status;
    sa.tick_status = sb.tick_status;
    EXPECT_EQ(std::memcmp(&sa, &sb, sizeof sa), 0) << bad;
  }
}

TEST(RcsiGuards, NonFiniteSideCurrentIsRejectedAndHeld) {
  Estimator est(base_config());
  warm_up(est, 10);
  const Estimator::Vector theta = est.theta();
  const Estimator::Matrix p = est.p();
  const double y0_prev = est.regressor()(1);
  const double u_hat = est.predict();
  const StatusWord status = est.update(0.01, std::numeric_limits<double>::quiet_NaN());
  EXPECT_TRUE(has_status(status, FwStatus::kRejectedNonFinite));
  EXPECT_EQ(est.theta(), theta);
  EXPECT_EQ(est.p(), p);
  EXPECT_EQ(est.regressor()(0), u_hat);
  EXPECT_EQ(est.regressor()(1), y0_prev);  // held, never NaN in the history
}

TEST(RcsiGuards, ClippingSetsItsBit) {
  auto c = base_config();
  c.theta0 << 100.0, 0.0;  // u_hat(0) = 100 * 0.2 = 20 > 10
  Estimator est(c);
  EXPECT_EQ(est.predict(), 10.0);
  EXPECT_TRUE(has_status(est.tick_status(), FwStatus::kOutputClipped));
  est.advance_without_learning(1.0);
  EXPECT_EQ(est.regressor()(0), 10.0) << "the history holds the applied (clipped) value";

  c.theta0 << -100.0, 0.0;
  Estimator low(c);
  EXPECT_EQ(low.predict(), -10.0);
  EXPECT_TRUE(has_status(low.status(), FwStatus::kOutputClipped));

  Estimator inside(base_config());
  inside.predict();
  EXPECT_FALSE(has_status(inside.tick_status(), FwStatus::kOutputClipped));
}

TEST(RcsiGuards, TraceCapSetsItsBitAndBoundsP) {
  auto c = base_config();
  c.lambda = 0.5;
  c.p_trace_cap_factor = 4.0;  // trace(P0) = 2 -> cap 8
  Estimator est(c);
  est.reset_history(0.0, 0.0);  // zero regressor: no excitation, P grows as 2^k
  bool capped = false;
  for (int k = 0; k < 10; ++k) {
    est.predict();
    const StatusWord s = est.update(0.0, 0.0);
    capped = capped || has_status(s, FwStatus::kCovarianceCapped);
    EXPECT_LE(est.p().trace(), 8.0 * (1.0 + 1e-15));
  }
  EXPECT_TRUE(capped);
  EXPECT_NEAR(est.p().trace(), 8.0, 1e-12);
  EXPECT_EQ(est.p(), est.p().transpose());
}

TEST(RcsiGuards, RlsRestoresLastGoodThetaOnOverflow) {
  bms::fw::RlsConfig<double, 2> c;
  c.p0_diag.setConstant(1e300);
  c.p_trace_cap_factor = 1.0;
  bms::fw::Rls<double, 2> rls(c);
  const Eigen::Vector2d theta = rls.theta();
  const Eigen::Matrix2d p = rls.p();
  // phi^T P phi overflows to inf: the update is discarded.
  const StatusWord s = rls.update(Eigen::Vector2d(1e10, 1e10), 1.0);
  EXPECT_TRUE(has_status(s, FwStatus::kThetaRestored));
  EXPECT_EQ(rls.theta(), theta);
  EXPECT_EQ(rls.p(), p);
}

TEST(RcsiGuards, UpdateWithoutPredictIsFlaggedAndIgnored) {
  Estimator est(base_config());
  warm_up(est, 3);
  const Estimator::State before = est.save();
  const StatusWord s = est.update(0.1, 1.0);
  EXPECT_TRUE(has_status(s, FwStatus::kCallOrder));
  Estimator::State after = est.save();
  after.status = before.status;
  after.tick_status = before.tick_status;
  EXPECT_EQ(std::memcmp(&before, &after, sizeof before), 0);
  // predict() twice is harmless: the same value.
  const double u1 = est.predict();
  const double u2 = est.predict();
  EXPECT_EQ(u1, u2);
}

TEST(RcsiGuards, InvalidConfigurationsAreFlaggedAndInert) {
  auto check_invalid = [](Estimator::Config c, const char* what) {
    EXPECT_FALSE(Estimator::validate(c)) << what;
    Estimator est(c);
    EXPECT_FALSE(est.config_ok()) << what;
    EXPECT_TRUE(has_status(est.status(), FwStatus::kConfigInvalid)) << what;
    const double u = est.predict();
    EXPECT_TRUE(std::isfinite(u)) << what;
    est.update(1.0, 1.0);
    EXPECT_TRUE(est.theta().allFinite()) << what;
  };
  auto c = base_config();
  c.markov_v_per_ohm_m2 = 0.0;
  check_invalid(c, "H = 0");
  c = base_config();
  c.lambda = 0.0;
  check_invalid(c, "lambda = 0");
  c = base_config();
  c.lambda = 1.5;
  check_invalid(c, "lambda > 1");
  c = base_config();
  c.p0_u = -1.0;
  check_invalid(c, "P0 < 0");
  c = base_config();
  c.eta = -1.0;
  check_invalid(c, "eta < 0");
  c = base_config();
  c.r_film_min_ohm_m2 = 1.0;
  c.r_film_max_ohm_m2 = 0.0;
  check_invalid(c, "min > max");
  c = base_config();
  c.theta0(0) = std::nan("");
  check_invalid(c, "NaN theta0");
  c = base_config();
  c.p_trace_cap_factor = 0.5;
  check_invalid(c, "cap below trace(P0)");
  EXPECT_TRUE(Estimator::validate(base_config()));
}

TEST(RcsiGuards, SetMarkovParameterRejectsZeroAndNonFinite) {
  Estimator est(base_config());
  EXPECT_FALSE(est.set_markov_parameter(0.0));
  EXPECT_FALSE(est.set_markov_parameter(std::numeric_limits<double>::infinity()));
  EXPECT_EQ(est.markov_parameter(), 0.5);
  EXPECT_TRUE(has_status(est.status(), FwStatus::kConfigInvalid));
  EXPECT_TRUE(est.set_markov_parameter(-0.5));  // discharge: the sign flips
  EXPECT_EQ(est.markov_parameter(), -0.5);
}

// Property test: random huge, tiny, subnormal, zero and non-finite inputs, random call
// orders, resets and H changes. Invariants after every call: theta and P finite, P exactly
// symmetric with a positive diagonal, u_hat finite and inside [min, max].
template <typename Scalar, int Nc, int D>
void adversarial(std::uint32_t seed, int steps) {
  using Est = bms::fw::RcsiEstimator<Scalar, Nc, D>;
  typename Est::Config c;
  c.markov_v_per_ohm_m2 = Scalar(0.01);
  c.lambda = Scalar(0.95);
  c.p0_u = Scalar(1);
  c.p0_y0 = Scalar(1e-3);
  c.p_trace_cap_factor = Scalar(100);
  c.theta0.setZero();
  c.theta0(0) = Scalar(1);
  c.r_film_init_ohm_m2 = Scalar(3.4e-3);
  c.j_side_init_a_m3 = Scalar(-10);
  c.r_film_min_ohm_m2 = Scalar(0);
  c.r_film_max_ohm_m2 = Scalar(1);
  Est est(c);
  ASSERT_TRUE(est.config_ok());

  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> pick(0, 15);
  std::uniform_real_distribution<double> exponent(-40.0, 40.0);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const Scalar kMax = std::numeric_limits<Scalar>::max();
  auto draw = [&]() -> Scalar {
    switch (pick(rng)) {
      case 0: return std::numeric_limits<Scalar>::quiet_NaN();
      case 1: return std::numeric_limits<Scalar>::infinity();
      case 2: return -std::numeric_limits<Scalar>::infinity();
      case 3: return kMax;
      case 4: return -kMax;
      case 5: return std::numeric_limits<Scalar>::denorm_min();
      case 6: return Scalar(0);
      case 7: return std::numeric_limits<Scalar>::min();
      case 8:
      case 9: return static_cast<Scalar>(unit(rng) * std::pow(10.0, exponent(rng)));
      default: return static_cast<Scalar>(unit(rng));
    }
  };
  StatusWord seen = 0u;
  for (int k = 0; k < steps; ++k) {
    const int op = pick(rng);
    if (op == 0) {
      est.reset();
    } else if (op == 1) {
      est.set_markov_parameter(draw());
    } else if (op == 2) {
      est.update(draw(), draw());  // possibly without predict()
    } else {
      const Scalar u = est.predict();
      ASSERT_TRUE(std::isfinite(u)) << k;
      ASSERT_GE(u, c.r_film_min_ohm_m2) << k;
      ASSERT_LE(u, c.r_film_max_ohm_m2) << k;
      if (op == 3) {
        est.advance_without_learning(draw());
      } else {
        est.update(draw(), draw());
      }
    }
    seen |= est.status();
    ASSERT_TRUE(est.theta().allFinite()) << k;
    ASSERT_TRUE(est.p().allFinite()) << k;
    ASSERT_TRUE(est.p() == est.p().transpose()) << k;
    ASSERT_TRUE((est.p().diagonal().array() > Scalar(0)).all()) << k;
    ASSERT_TRUE(est.regressor().allFinite()) << k;
    ASSERT_TRUE(std::isfinite(est.u_hat_ohm_m2())) << k;
  }
  // The run exercised the guards.
  EXPECT_TRUE(has_status(seen, FwStatus::kRejectedNonFinite));
  EXPECT_TRUE(has_status(seen, FwStatus::kOutputClipped));
  EXPECT_TRUE(has_status(seen, FwStatus::kCallOrder));
  EXPECT_TRUE(has_status(seen, FwStatus::kConfigInvalid));
}

TEST(RcsiGuards, AdversarialDouble) { adversarial<double, 1, 1>(2024u, 100000); }
TEST(RcsiGuards, AdversarialDoubleOrder2Delay0) { adversarial<double, 2, 0>(7u, 100000); }
TEST(RcsiGuards, AdversarialFloat) { adversarial<float, 1, 1>(31337u, 100000); }
TEST(RcsiGuards, AdversarialFloatOrder8Delay2) { adversarial<float, 8, 2>(5u, 20000); }

}  // namespace
