// Every supported instantiation compiles and runs: double and float, n_c = 1, 2, 8,
// delays 0..2. Explicit instantiation compiles every member, not only the ones used.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstddef>
#include <cstring>

#include <bms/fw/estimation/rcsi_estimator.hpp>
#include <bms/fw/estimation/rls_arx.hpp>
#include "bms/fw/model/paper_cell.hpp"

template class bms::fw::RcsiEstimator<double, 1, 1>;
template class bms::fw::RcsiEstimator<double, 2, 1>;
template class bms::fw::RcsiEstimator<double, 8, 1>;
template class bms::fw::RcsiEstimator<double, 8, 0>;
template class bms::fw::RcsiEstimator<float, 1, 1>;
template class bms::fw::RcsiEstimator<float, 2, 0>;
template class bms::fw::RcsiEstimator<float, 8, 2>;
template class bms::fw::RlsArxFit<double, 8>;
template class bms::fw::RlsArxFit<float, 2>;
template class bms::fw::Rls<float, 16>;

namespace {

template <typename T>
class RcsiInstantiation : public ::testing::Test {};

template <typename Scalar, int Nc, int D>
struct Params {
  using S = Scalar;
  static constexpr int kNc = Nc;
  static constexpr int kD = D;
};

using AllParams =
    ::testing::Types<Params<double, 1, 1>, Params<double, 2, 1>, Params<double, 8, 1>,
                     Params<double, 8, 0>, Params<float, 1, 1>, Params<float, 2, 0>,
                     Params<float, 8, 2>>;
TYPED_TEST_SUITE(RcsiInstantiation, AllParams);

// Smoke test in the paper's setting (H = 0.01, P0 = 5e-7) with a consistent target: the
// "true" film resistance is 3.2e-3 ohm.m2, so z(k) = H (u_hat(k-D) - 3.2e-3) and u* = 3.2e-3.
// Checks that every instantiation runs, learns, stays finite and bounded without any guard
// firing, and saves/restores. (Convergence is the toy-plant tests' job: with a nearly
// constant u_hat and J_s the two regressors are almost collinear, so this loop settles
// slowly.)
TYPED_TEST(RcsiInstantiation, RunsAndLearns) {
  using S = typename TypeParam::S;
  constexpr int kD = TypeParam::kD;
  using Est = bms::fw::RcsiEstimator<S, TypeParam::kNc, kD>;
  typename Est::Config c;
  c.markov_v_per_ohm_m2 = S(0.01);
  c.p0_u = S(5e-7);
  c.p0_y0 = S(5e-7);
  c.theta0.setZero();
  c.theta0(0) = S(1);
  c.r_film_init_ohm_m2 = S(bms::fw::paper::kInitialFilm_ohm_m2);
  c.j_side_init_a_m3 = S(-10);
  c.r_film_min_ohm_m2 = S(1e-4);
  c.r_film_max_ohm_m2 = S(1e-1);
  Est est(c);
  ASSERT_TRUE(est.config_ok());
  EXPECT_EQ(Est::kNumRegressors, 2 * TypeParam::kNc);
  const S target = S(3.2e-3);
  std::array<S, kD + 1> u_hat_history{};  // u_hat(k), u_hat(k-1), ..., u_hat(k-D)
  for (int k = 0; k < 2000; ++k) {
    for (int j = kD; j > 0; --j) {
      u_hat_history[static_cast<std::size_t>(j)] = u_hat_history[static_cast<std::size_t>(j - 1)];
    }
    u_hat_history[0] = est.predict();
    ASSERT_TRUE(std::isfinite(u_hat_history[0]));
    const S z = c.markov_v_per_ohm_m2 * (u_hat_history[kD] - target);
    est.update(z, S(-10) + S(0.5) * static_cast<S>(std::sin(0.05 * k)));
  }
  EXPECT_NE(est.theta(), c.theta0);
  EXPECT_TRUE(est.theta().allFinite());
  EXPECT_LT(std::abs(est.u_hat_ohm_m2() - target), S(1e-3));
  EXPECT_EQ(est.status() & ~bms::fw::bit(bms::fw::FwStatus::kCovarianceCapped), 0u);
  Est copy(c);
  ASSERT_TRUE(copy.restore(est.save()));
  const typename Est::State a = est.save();
  const typename Est::State b = copy.save();
  EXPECT_EQ(std::memcmp(&a, &b, sizeof a), 0);
}

}  // namespace
