#pragma once
// Strictly proper ARX regressor of order Nc and plain (offline) RLS on recorded sequences.
//
// Model (paper eqs 43-46):  u(k) = theta^T phi(k-1),
//   phi(k-1) = [u(k-1) ... u(k-Nc), y0(k-1) ... y0(k-Nc)]^T,
//   theta    = [M1 ... MNc, N1 ... NNc]^T.
// In the SEI application u is the film resistance [ohm.m2] and y0 the side-reaction current
// density J_s [A/m3].
//
// RlsArxFit is the paper's figure-7 experiment: with the u_hat and y0_hat recorded from an
// RCSI run (or a simulation) and a large P(0) (1e10), plain RLS recovers the true subsystem
// theta = [1, -2.3712e-10]. With parameters that far apart use Scalar = double.
#include <cmath>
#include <cstddef>
#include <cstdint>

#include <Eigen/Core>

#include "bms/fw/estimation/fw_status.hpp"
#include "bms/fw/estimation/rls.hpp"

namespace bms::fw {

// Shifts one sample into an ARX regressor: phi(k-1) -> phi(k) given u(k) and y0(k).
template <typename Scalar, int Nc>
void rls_arx_push(Eigen::Matrix<Scalar, 2 * Nc, 1>& phi, Scalar u, Scalar y0) {
  for (int i = Nc - 1; i > 0; --i) {
    phi(i) = phi(i - 1);
    phi(Nc + i) = phi(Nc + i - 1);
  }
  phi(0) = u;
  phi(Nc) = y0;
}

template <typename Scalar, int Nc>
class RlsArxFit {
  static_assert(Nc >= 1 && Nc <= 8, "ARX order must be in 1..8");

 public:
  static constexpr int kNumRegressors = 2 * Nc;
  using RlsType = Rls<Scalar, kNumRegressors>;
  using Vector = typename RlsType::Vector;
  using Config = typename RlsType::Config;

  explicit RlsArxFit(const Config& config) : rls_(config) {}

  // Feed the recorded u(k), y0(k) in time order. Once Nc samples are known, every further u(k)
  // is regressed on phi(k-1). A non-finite sample is rejected (kRejectedNonFinite) and
  // restarts the regressor window, so no regression ever uses it.
  StatusWord add_sample(Scalar u, Scalar y0) {
    if (!std::isfinite(u) || !std::isfinite(y0)) {
      known_ = 0;
      return bit(FwStatus::kRejectedNonFinite);
    }
    StatusWord status = 0u;
    if (known_ >= Nc) {
      status |= rls_.update(phi_, u);
      ++updates_;
    }
    rls_arx_push<Scalar, Nc>(phi_, u, y0);
    if (known_ < Nc) {
      ++known_;
    }
    return status;
  }

  // Restores theta(0), P(0) and empties the regressor window.
  void reset() {
    rls_.reset();
    phi_.setZero();
    known_ = 0;
    updates_ = 0u;
  }

  const Vector& theta() const { return rls_.theta(); }
  const RlsType& rls() const { return rls_; }
  std::uint32_t updates() const { return updates_; }

 private:
  RlsType rls_;
  Vector phi_ = Vector::Zero();
  int known_ = 0;                // samples in the window, saturates at Nc
  std::uint32_t updates_ = 0u;   // RLS steps taken
};

// Offline fit over two recorded arrays of equal length; returns the OR of all status bits.
template <typename Scalar, int Nc>
StatusWord rls_fit_arx_offline(RlsArxFit<Scalar, Nc>& fit, const Scalar* u, const Scalar* y0,
                               std::size_t count) {
  StatusWord status = 0u;
  for (std::size_t k = 0; k < count; ++k) {
    status |= fit.add_sample(u[k], y0[k]);
  }
  return status;
}

}  // namespace bms::fw
