#pragma once
// Recursive least squares with exponential forgetting, guarded for firmware use.
//
// Fits target(k) ~ theta^T phi(k) by minimising
//   sum_i lambda^(k-i) (target(i) - phi(i)^T theta)^2
//     + lambda^k (theta - theta0)^T P0^-1 (theta - theta0)
// with the standard recursion (paper eqs 47-49 with the reset a(k) = 0, clean form in
// shared/reference/models.md section 4):
//   e     = target - phi^T theta
//   K     = P phi / (lambda + phi^T P phi)
//   theta = theta + K e
//   P     = (P - K phi^T P) / lambda        (both terms divided by lambda)
// Guards, each reported by a status bit (bms/fw/estimation/fw_status.hpp), never silent:
//   - non-finite phi or target: no update (kRejectedNonFinite);
//   - non-finite result, non-positive gain denominator or a non-positive diagonal of P:
//     the update is discarded, the last good theta and P are kept (kThetaRestored);
//   - P is symmetrised after every update; trace(P) is capped at
//     p_trace_cap_factor * trace(P0) by scaling P (kCovarianceCapped). With lambda < 1 this
//     bounds the wind-up of P in unexcited directions.
//
// Firmware rules: fixed-size Eigen only, no heap, no exceptions. Scalar = double or float.
// Note: parameters of very different size (the paper's theta = [1, -2.3712e-10]) need
// double; with float the smaller parameter is below the resolution of the larger one.
#include <cmath>
#include <cstdint>
#include <type_traits>

#include <Eigen/Core>

#include "bms/fw/estimation/fw_status.hpp"

namespace bms::fw {

template <typename Scalar, int N>
struct RlsConfig {
  using Vector = Eigen::Matrix<Scalar, N, 1>;
  Scalar lambda = Scalar(1);                     // forgetting factor, in (0, 1]
  Vector p0_diag = Vector::Constant(Scalar(1));  // P(0) = diag(p0_diag); every entry > 0
  Vector theta0 = Vector::Zero();                // theta(0)
  Scalar p_trace_cap_factor = Scalar(1);         // trace(P) <= factor * trace(P(0)); >= 1
};

template <typename Scalar, int N>
class Rls {
  static_assert(std::is_floating_point<Scalar>::value, "Scalar must be a floating-point type");
  static_assert(N >= 1 && N <= 32, "the number of regressors must be in 1..32");

 public:
  using Vector = Eigen::Matrix<Scalar, N, 1>;
  using Matrix = Eigen::Matrix<Scalar, N, N>;
  using Config = RlsConfig<Scalar, N>;

  // Plain-old-data image of the learned state (P column-major), for non-volatile memory.
  struct State {
    Scalar theta[N];
    Scalar p[N * N];
  };
  static_assert(std::is_trivially_copyable<State>::value, "State must be trivially copyable");
  static_assert(std::is_standard_layout<State>::value, "State must be standard layout");

  explicit Rls(const Config& config)
      : config_(config), config_ok_(validate(config)), p_trace_cap_(config.p0_diag.sum()) {
    if (config_ok_) {
      p_trace_cap_ *= config.p_trace_cap_factor;
    }
    reset();
  }

  static bool validate(const Config& c) {
    return std::isfinite(c.lambda) && c.lambda > Scalar(0) && c.lambda <= Scalar(1) &&
           c.p0_diag.allFinite() && (c.p0_diag.array() > Scalar(0)).all() &&
           c.theta0.allFinite() && std::isfinite(c.p_trace_cap_factor) &&
           c.p_trace_cap_factor >= Scalar(1) && std::isfinite(c.p0_diag.sum());
  }

  // theta <- theta(0), P <- P(0). With an invalid configuration: theta = 0, P = I (inert).
  void reset() {
    if (config_ok_) {
      theta_ = config_.theta0;
      p_ = config_.p0_diag.asDiagonal();
    } else {
      theta_.setZero();
      p_.setIdentity();
    }
  }

  // One RLS step with regressor phi and target; returns the status bits raised.
  StatusWord update(const Vector& phi, Scalar target) {
    if (!config_ok_) {
      return bit(FwStatus::kConfigInvalid);
    }
    if (!phi.allFinite() || !std::isfinite(target)) {
      return bit(FwStatus::kRejectedNonFinite);
    }
    const Vector p_phi = p_ * phi;
    const Scalar denom = config_.lambda + phi.dot(p_phi);
    if (!std::isfinite(denom) || !(denom > Scalar(0))) {
      return bit(FwStatus::kThetaRestored);
    }
    const Vector gain = p_phi / denom;
    const Scalar error = target - theta_.dot(phi);
    const Vector theta_new = theta_ + gain * error;
    // P is symmetric, so phi^T P = (P phi)^T.
    const Matrix p_raw = (p_ - gain * p_phi.transpose()) / config_.lambda;
    // (a + b) / 2 is commutative in IEEE arithmetic: the result is exactly symmetric.
    Matrix p_new = Scalar(0.5) * (p_raw + p_raw.transpose());
    if (!theta_new.allFinite() || !p_new.allFinite() ||
        !(p_new.diagonal().array() > Scalar(0)).all()) {
      return bit(FwStatus::kThetaRestored);
    }
    StatusWord status = 0u;
    const Scalar trace = p_new.trace();
    if (trace > p_trace_cap_) {
      p_new *= p_trace_cap_ / trace;
      status |= bit(FwStatus::kCovarianceCapped);
    }
    theta_ = theta_new;
    p_ = p_new;
    return status;
  }

  Scalar predict(const Vector& phi) const { return theta_.dot(phi); }

  const Vector& theta() const { return theta_; }
  const Matrix& p() const { return p_; }
  const Config& config() const { return config_; }
  bool config_ok() const { return config_ok_; }
  Scalar p_trace_cap() const { return p_trace_cap_; }

  State save() const {
    State s{};
    Eigen::Map<Vector>(s.theta) = theta_;
    Eigen::Map<Matrix>(s.p) = p_;
    return s;
  }

  // Accepts a state with finite theta and an exactly symmetric, finite P with a positive
  // diagonal; otherwise changes nothing and returns false.
  bool restore(const State& s) {
    const Eigen::Map<const Vector> theta(s.theta);
    const Eigen::Map<const Matrix> p(s.p);
    if (!is_valid_state(theta, p)) {
      return false;
    }
    theta_ = theta;
    p_ = p;
    return true;
  }

 private:
  template <typename ThetaT, typename PT>
  static bool is_valid_state(const ThetaT& theta, const PT& p) {
    return theta.allFinite() && p.allFinite() && (p.diagonal().array() > Scalar(0)).all() &&
           p == p.transpose();
  }

  Config config_;
  bool config_ok_;
  Scalar p_trace_cap_;
  Vector theta_;
  Matrix p_;
};

}  // namespace bms::fw
