// RCSI on linear toy plants with a known subsystem in feedback: checks the sign of H, the
// delay convention d and the index of the regressor (phi(k-d-1) for u*(k-d)).
//
// Truth:  x(k+1) = A x(k) + B u(k) + Dw w(k),  y(k) = E x(k) + F u(k),  y0(k) = C0 x(k),
//         u(k) = M1 u(k-1) + N1 y0(k-1)                      (the "unknown" subsystem)
// Model:  the same main system driven by u_hat(k) from the estimator, same initial state.
// Plants ("exact"): z(k) depends on u_hat only through u_hat(k-d) - u(k-d), so the
// retrospective step with H = first Markov parameter recovers the true past input exactly.
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <random>

#include <Eigen/Core>

#include <bms/fw/estimation/fw_status.hpp>
#include <bms/fw/estimation/rcsi_estimator.hpp>
#include <bms/fw/estimation/rcsi_retrospective.hpp>

namespace {

using bms::fw::FwStatus;
using bms::fw::has_status;
using bms::fw::RcsiEstimator;

constexpr double kM1 = 0.8;  // true subsystem theta = [M1, N1]
constexpr double kN1 = 0.3;

template <typename Scalar>
struct ToyPlant {
  using Mat3 = Eigen::Matrix<Scalar, 3, 3>;
  using Vec3 = Eigen::Matrix<Scalar, 3, 1>;
  using Row3 = Eigen::Matrix<Scalar, 1, 3>;
  Mat3 a = Mat3::Zero();
  Vec3 b = Vec3::Zero();
  Vec3 dw = Vec3::Zero();
  Row3 e = Row3::Zero();
  Row3 c0 = Row3::Zero();
  Scalar f = Scalar(0);      // direct feedthrough u -> y
  Scalar markov = Scalar(0);  // first nonzero Markov parameter: F, E B or E A B
};

enum class PlantKind { kExactD0, kExactD1, kExactD2, kGeneralD1 };

// All closed loops (truth plant + subsystem) are stable; eigenvalue moduli <= 0.94.
template <typename Scalar>
ToyPlant<Scalar> make_plant(PlantKind kind) {
  ToyPlant<Scalar> p;
  p.dw << Scalar(0.5), Scalar(1.0), Scalar(0.0);
  p.c0 << Scalar(0), Scalar(1), Scalar(0);  // y0 = x2
  p.e << Scalar(1), Scalar(0), Scalar(0);   // y = x1 (+ F u)
  switch (kind) {
    case PlantKind::kExactD0:  // x1 is not driven by u: z(k) = F (u_hat(k) - u(k))
      p.a << Scalar(0), Scalar(0), Scalar(0), Scalar(0.3), Scalar(0.6), Scalar(0), Scalar(0),
          Scalar(0), Scalar(0.5);
      p.b << Scalar(0), Scalar(-0.4), Scalar(0);
      p.f = Scalar(0.7);
      p.markov = p.f;
      break;
    case PlantKind::kExactD1:  // E A = 0: z(k) = E B (u_hat(k-1) - u(k-1))
      p.a << Scalar(0), Scalar(0), Scalar(0), Scalar(0.1), Scalar(0.6), Scalar(0), Scalar(0),
          Scalar(0), Scalar(0.5);
      p.b << Scalar(2.5), Scalar(-0.4), Scalar(0);
      p.markov = p.e.dot(p.b);
      break;
    case PlantKind::kExactD2:  // E B = 0, E A^2 = 0: z(k) = E A B (u_hat(k-2) - u(k-2))
      p.a << Scalar(0), Scalar(0), Scalar(1), Scalar(0.1), Scalar(0.6), Scalar(0), Scalar(0),
          Scalar(0), Scalar(0);
      p.b << Scalar(0), Scalar(-0.4), Scalar(2.5);
      p.markov = p.e * p.a * p.b;
      break;
    case PlantKind::kGeneralD1:  // E A != 0: H = E B captures only the first Markov parameter
      p.a << Scalar(0.5), Scalar(0.2), Scalar(0), Scalar(-0.1), Scalar(0.6), Scalar(0), Scalar(0),
          Scalar(0), Scalar(0.5);
      p.b << Scalar(2.5), Scalar(-0.4), Scalar(0);
      p.markov = p.e.dot(p.b);
      break;
  }
  return p;
}

struct TickRecord {
  double z = 0.0;
  double u_hat = 0.0;
  double u_true = 0.0;
  double u_star = 0.0;          // u*(k-D), NaN when not computed
  double u_true_delayed = 0.0;  // u(k-D)
  double z_star_replay = 0.0;   // z(k) recomputed by the model with u_hat(k-D) := u*(k-D)
  bms::fw::StatusWord status = 0u;
};

// Truth plant + model copy + estimator. The model copy is replayed with u* to compute the
// retrospective performance z*(k) independently of the estimator's own algebra.
template <typename Scalar, int D>
class ClosedLoop {
 public:
  using Estimator = RcsiEstimator<Scalar, 1, D>;
  using Vec3 = typename ToyPlant<Scalar>::Vec3;

  ClosedLoop(const ToyPlant<Scalar>& plant, const typename Estimator::Config& config)
      : plant_(plant), est_(config) {}

  TickRecord tick() {
    const Scalar w = uniform_(rng_);
    // Truth.
    const Scalar y0 = plant_.c0.dot(x_);
    const Scalar u = Scalar(kM1) * u_prev_ + Scalar(kN1) * y0_prev_;
    const Scalar y = plant_.e.dot(x_) + plant_.f * u;
    // Model and estimator, in the documented order.
    const Scalar u_hat = est_.predict();
    const Scalar y_hat = plant_.e.dot(x_hat_) + plant_.f * u_hat;
    const Scalar y0_hat = plant_.c0.dot(x_hat_);
    const Scalar z = y_hat - y;
    TickRecord r;
    r.status = est_.update(z, y0_hat);
    const Scalar u_star = est_.u_star_ohm_m2();

    // Histories (index k mod kRing); slot k holds the values of this tick.
    const std::size_t s = slot(k_);
    x_hat_hist_[s] = x_hat_;
    u_hat_hist_[s] = u_hat;
    w_hist_[s] = w;
    u_hist_[s] = u;

    r.z = static_cast<double>(z);
    r.u_hat = static_cast<double>(u_hat);
    r.u_true = static_cast<double>(u);
    r.u_star = static_cast<double>(u_star);
    if (k_ >= D) {
      r.u_true_delayed = static_cast<double>(u_hist_[slot(k_ - D)]);
      r.z_star_replay = static_cast<double>(replay_z_star(u_star, y));
    }

    // Advance truth and model.
    x_ = plant_.a * x_ + plant_.b * u + plant_.dw * w;
    x_hat_ = plant_.a * x_hat_ + plant_.b * u_hat + plant_.dw * w;
    u_prev_ = u;
    y0_prev_ = y0;
    ++k_;
    return r;
  }

  const Estimator& estimator() const { return est_; }

 private:
  static constexpr std::size_t kRing = 16;
  static std::size_t slot(std::int64_t k) { return static_cast<std::size_t>(k) % kRing; }

  // Replays the model from x_hat(k-D) with u_hat(k-D) replaced by u*, then y_hat(k) - y(k).
  Scalar replay_z_star(Scalar u_star, Scalar y) const {
    if constexpr (D == 0) {
      return plant_.e.dot(x_hat_) + plant_.f * u_star - y;
    } else {
      Vec3 xr = x_hat_hist_[slot(k_ - D)];
      for (int j = D; j >= 1; --j) {
        const std::size_t sj = slot(k_ - j);
        const Scalar u_use = (j == D) ? u_star : u_hat_hist_[sj];
        xr = plant_.a * xr + plant_.b * u_use + plant_.dw * w_hist_[sj];
      }
      return plant_.e.dot(xr) + plant_.f * u_hat_hist_[slot(k_)] - y;
    }
  }

  ToyPlant<Scalar> plant_;
  Estimator est_;
  Vec3 x_ = Vec3::Zero();
  Vec3 x_hat_ = Vec3::Zero();
  Scalar u_prev_ = Scalar(0);
  Scalar y0_prev_ = Scalar(0);
  std::int64_t k_ = 0;
  std::array<Vec3, kRing> x_hat_hist_{};
  std::array<Scalar, kRing> u_hat_hist_{};
  std::array<Scalar, kRing> w_hist_{};
  std::array<Scalar, kRing> u_hist_{};
  std::mt19937 rng_{12345u};
  std::uniform_real_distribution<Scalar> uniform_{Scalar(-1), Scalar(1)};  // PE input
};

template <typename Scalar, int D>
typename RcsiEstimator<Scalar, 1, D>::Config toy_config(const ToyPlant<Scalar>& plant,
                                                         Scalar lambda, Scalar p0) {
  typename RcsiEstimator<Scalar, 1, D>::Config c;
  c.markov_v_per_ohm_m2 = plant.markov;
  c.eta = Scalar(0);
  c.lambda = lambda;
  c.p0_u = p0;
  c.p0_y0 = p0;
  c.p_trace_cap_factor = Scalar(1);
  c.theta0.setZero();
  c.r_film_init_ohm_m2 = Scalar(0);
  c.j_side_init_a_m3 = Scalar(0);
  c.r_film_min_ohm_m2 = Scalar(-1e3);
  c.r_film_max_ohm_m2 = Scalar(1e3);
  return c;
}

template <typename Scalar, int D>
double theta_error(const RcsiEstimator<Scalar, 1, D>& est) {
  return std::max(std::abs(static_cast<double>(est.theta()(0)) - kM1),
                  std::abs(static_cast<double>(est.theta()(1)) - kN1));
}

// (a) Replaying the model with u*(k-D) in place of u_hat(k-D) zeroes z(k): holds for any
// plant when H is the exact first Markov parameter, whatever theta is. A wrong sign of H
// gives z* = 2 z, a wrong delay gives z* != 0.
template <int D>
void expect_replay_zeroes_z(PlantKind kind) {
  const auto plant = make_plant<double>(kind);
  ClosedLoop<double, D> loop(plant, toy_config<double, D>(plant, 1.0, 1.0));
  double max_abs_z = 0.0;
  double max_abs_z_star = 0.0;
  int checked = 0;
  for (int k = 0; k < 3000; ++k) {
    const TickRecord r = loop.tick();
    if (k < D) {
      EXPECT_TRUE(std::isnan(r.u_star)) << "no u* before u_hat(k-D) exists, k=" << k;
      continue;
    }
    ASSERT_FALSE(std::isnan(r.u_star)) << "k=" << k;
    max_abs_z = std::max(max_abs_z, std::abs(r.z));
    max_abs_z_star = std::max(max_abs_z_star, std::abs(r.z_star_replay) / (1.0 + std::abs(r.z)));
    ++checked;
  }
  EXPECT_EQ(checked, 3000 - D);
  EXPECT_GT(max_abs_z, 0.1) << "the test must start from a wrong theta (z clearly nonzero)";
  EXPECT_LT(max_abs_z_star, 1e-13);
}

TEST(RcsiToyPlant, ReplayWithUStarZeroesZDelay0) { expect_replay_zeroes_z<0>(PlantKind::kExactD0); }
TEST(RcsiToyPlant, ReplayWithUStarZeroesZDelay1) { expect_replay_zeroes_z<1>(PlantKind::kExactD1); }
TEST(RcsiToyPlant, ReplayWithUStarZeroesZDelay1GeneralPlant) {
  expect_replay_zeroes_z<1>(PlantKind::kGeneralD1);
}
TEST(RcsiToyPlant, ReplayWithUStarZeroesZDelay2) { expect_replay_zeroes_z<2>(PlantKind::kExactD2); }

// (a) On the exact plants u*(k-D) is the true past subsystem output u(k-D), even with a
// wrong theta (tiny P0 keeps theta wrong, so u_hat stays far from u).
template <int D>
void expect_u_star_equals_true_past_u(PlantKind kind) {
  const auto plant = make_plant<double>(kind);
  ClosedLoop<double, D> loop(plant, toy_config<double, D>(plant, 1.0, 1e-12));
  double max_u_error = 0.0;
  double max_u_star_error = 0.0;
  for (int k = 0; k < 2000; ++k) {
    const TickRecord r = loop.tick();
    if (k < D) {
      continue;
    }
    max_u_error = std::max(max_u_error, std::abs(r.u_hat - r.u_true));
    max_u_star_error = std::max(max_u_star_error, std::abs(r.u_star - r.u_true_delayed));
  }
  EXPECT_GT(max_u_error, 0.1);
  EXPECT_LT(max_u_star_error, 1e-12);
  EXPECT_LT(std::abs(loop.estimator().theta()(0)), 1e-6) << "theta must have stayed wrong";
}

TEST(RcsiToyPlant, UStarIsTruePastInputDelay0) {
  expect_u_star_equals_true_past_u<0>(PlantKind::kExactD0);
}
TEST(RcsiToyPlant, UStarIsTruePastInputDelay1) {
  expect_u_star_equals_true_past_u<1>(PlantKind::kExactD1);
}
TEST(RcsiToyPlant, UStarIsTruePastInputDelay2) {
  expect_u_star_equals_true_past_u<2>(PlantKind::kExactD2);
}

// (a) At the true theta (and the true initial state) the model reproduces the truth: z = 0,
// u* = u_hat = u, and theta does not move.
TEST(RcsiToyPlant, TrueThetaGivesZeroErrorAndZeroStar) {
  const auto plant = make_plant<double>(PlantKind::kGeneralD1);
  auto config = toy_config<double, 1>(plant, 1.0, 1.0);
  config.theta0 << kM1, kN1;
  ClosedLoop<double, 1> loop(plant, config);
  for (int k = 0; k < 2000; ++k) {
    const TickRecord r = loop.tick();
    ASSERT_LT(std::abs(r.z), 1e-13) << "k=" << k;
    ASSERT_LT(std::abs(r.u_hat - r.u_true), 1e-13) << "k=" << k;
    if (k >= 1) {
      ASSERT_LT(std::abs(r.u_star - r.u_true_delayed), 1e-12) << "k=" << k;
      ASSERT_LT(std::abs(r.z_star_replay), 1e-13) << "k=" << k;
    }
  }
  EXPECT_LT(theta_error(loop.estimator()), 1e-12);
}

// (b) RLS recovers the true theta on the exact plants (H exact) and z goes to ~0.
// Forgetting (lambda = 0.99) discards the early samples, whose regressors (u_hat, y0_hat)
// still differed from the truth's.
template <int D>
void expect_recovers_theta(PlantKind kind) {
  const auto plant = make_plant<double>(kind);
  ClosedLoop<double, D> loop(plant, toy_config<double, D>(plant, 0.99, 1.0));
  double max_abs_z_tail = 0.0;
  double max_abs_z_head = 0.0;
  const int steps = 20000;
  for (int k = 0; k < steps; ++k) {
    const TickRecord r = loop.tick();
    ASSERT_FALSE(has_status(r.status, FwStatus::kOutputClipped)) << "k=" << k;
    if (k < 200) {
      max_abs_z_head = std::max(max_abs_z_head, std::abs(r.z));
    }
    if (k >= steps - 1000) {
      max_abs_z_tail = std::max(max_abs_z_tail, std::abs(r.z));
    }
  }
  EXPECT_GT(max_abs_z_head, 0.1);
  EXPECT_LT(theta_error(loop.estimator()), 1e-10);
  EXPECT_LT(max_abs_z_tail, 1e-12);
}

TEST(RcsiToyPlant, RecoversThetaDelay0) { expect_recovers_theta<0>(PlantKind::kExactD0); }
TEST(RcsiToyPlant, RecoversThetaDelay1) { expect_recovers_theta<1>(PlantKind::kExactD1); }
TEST(RcsiToyPlant, RecoversThetaDelay2) { expect_recovers_theta<2>(PlantKind::kExactD2); }

// With E A != 0, H = E B is only the first Markov parameter: u* is biased while the model
// state differs from the truth, but the bias vanishes as theta converges. Without
// forgetting the early biased samples are averaged out slowly (about 1/k).
TEST(RcsiToyPlant, ConvergesOnGeneralPlantWithFirstMarkovParameterOnly) {
  const auto plant = make_plant<double>(PlantKind::kGeneralD1);
  ClosedLoop<double, 1> loop(plant, toy_config<double, 1>(plant, 1.0, 1.0));
  double max_abs_z_tail = 0.0;
  for (int k = 0; k < 20000; ++k) {
    const TickRecord r = loop.tick();
    if (k >= 19000) {
      max_abs_z_tail = std::max(max_abs_z_tail, std::abs(r.z));
    }
  }
  EXPECT_LT(theta_error(loop.estimator()), 1e-3);
  EXPECT_LT(max_abs_z_tail, 1e-2);
}

// Sensitivity. Note that the true theta is a fixed point of RCSI for any H and any d
// (z = 0 makes u* = u_hat), so convergence of theta alone does not validate H or d; the
// u* and z* tests above do. A wrong sign of H makes the loop move away from the fixed point.
TEST(RcsiToyPlant, WrongSignOfMarkovParameterFails) {
  auto plant = make_plant<double>(PlantKind::kExactD1);
  auto config = toy_config<double, 1>(plant, 0.99, 1.0);
  config.markov_v_per_ohm_m2 = -plant.markov;
  ClosedLoop<double, 1> loop(plant, config);
  for (int k = 0; k < 20000; ++k) {
    loop.tick();
  }
  EXPECT_GT(theta_error(loop.estimator()), 0.05);
}

TEST(RcsiToyPlant, WrongDelayGivesWrongRetrospectiveInput) {
  const auto plant = make_plant<double>(PlantKind::kExactD1);
  const auto good = toy_config<double, 1>(plant, 0.99, 1.0);
  RcsiEstimator<double, 1, 0>::Config wrong;  // D = 0 on a plant with delay 1
  wrong.markov_v_per_ohm_m2 = good.markov_v_per_ohm_m2;
  wrong.lambda = good.lambda;
  wrong.p0_u = good.p0_u;
  wrong.p0_y0 = good.p0_y0;
  wrong.r_film_min_ohm_m2 = good.r_film_min_ohm_m2;
  wrong.r_film_max_ohm_m2 = good.r_film_max_ohm_m2;
  ClosedLoop<double, 0> loop(plant, wrong);
  double max_u_star_error = 0.0;
  for (int k = 0; k < 20000; ++k) {
    const TickRecord r = loop.tick();
    max_u_star_error = std::max(max_u_star_error, std::abs(r.u_star - r.u_true_delayed));
  }
  // u*(k) of the D = 0 estimator is not the true u(k): the retrospective step is wrong.
  EXPECT_GT(max_u_star_error, 0.1);
}

// Float instantiation: same loop, looser tolerance.
TEST(RcsiToyPlant, FloatRecoversThetaDelay1) {
  const auto plant = make_plant<float>(PlantKind::kExactD1);
  ClosedLoop<float, 1> loop(plant, toy_config<float, 1>(plant, 0.99f, 1.0f));
  double max_abs_z_tail = 0.0;
  for (int k = 0; k < 20000; ++k) {
    const TickRecord r = loop.tick();
    ASSERT_EQ(r.status & ~bms::fw::bit(FwStatus::kCovarianceCapped), 0u) << "k=" << k;
    if (k >= 19000) {
      max_abs_z_tail = std::max(max_abs_z_tail, std::abs(r.z));
    }
  }
  EXPECT_LT(theta_error(loop.estimator()), 1e-4);
  EXPECT_LT(max_abs_z_tail, 1e-4);
}

}  // namespace
