#pragma once
// Retrospective-cost subsystem identification (RCSI) of the SEI film resistance.
//
// Signals (paper eqs 13-21; models.md section 4):
//   w      measured input (current in constant-current mode)
//   y      measured output (terminal voltage in constant-current mode)
//   y_hat  output of the main-system model, z = y_hat - y
//   u_hat  estimated subsystem output: film resistance [ohm.m2], fed to the model
//   y0_hat model's side-reaction current density J_s [A/m3], fed to the subsystem model
// The estimator is generic over the main-system model: it only sees u_hat, z and y0_hat.
//
// Subsystem model: strictly proper ARX of order Nc (bms/fw/estimation/rls_arx.hpp)
//   u_hat(k) = theta^T phi(k-1),  phi(k-1) = [u_hat(k-1..k-Nc), y0_hat(k-1..k-Nc)].
// Retrospective step (bms/fw/estimation/rcsi_retrospective.hpp), scalar H at delay D:
//   u*(k-D) = u_hat(k-D) - z(k)/H  (eta = 0),  regularised form for eta > 0.
// RLS (bms/fw/estimation/rls.hpp): fits theta^T phi(k-D-1) ~ u*(k-D), where phi(k-D-1) is exactly the
// regressor that produced u_hat(k-D).
//
// ---- Call order within one tick k: BmsCore::tick's steps 5, 6, 8 and 9 (the off-by-one in D is
// the classic RCSI bug) ----
//   step 5  r = est.predict();       u_hat(k) = theta^T phi(k-1), clipped; apply r to the model
//   step 6  the model runs its tick with u_hat(k) and gives y_hat and y0_hat of this tick
//   step 8  z = y_hat - y            (y measured at the same instant as y_hat)
//   step 9  est.update(z, y0_hat);   learns from u*(k-D), then stores u_hat(k), y0_hat(k)
// D is the number of ticks between the u_hat a z first depends on and that z:
//   D = 0  the y_hat of step 6 already depends on u_hat(k) (direct feedthrough: a DFN that
//          solves its algebraic equations with the updated film drop j*R_film at the same instant);
//   D = 1  the y_hat of step 6 depends only on u_hat(k-1) (paper eqs 17-18: x_hat(k+1) uses
//          u_hat(k) and y_hat(k) = h(x_hat(k)); the paper uses D = 1).
// Why predict comes first: it is the one order that is valid for both D = 0 and D >= 1
// (with D = 0, z(k) cannot exist before u_hat(k)). For D >= 1 the cost is that u_hat(k) uses
// theta fitted up to z(k-1) rather than z(k) (the paper's eq. 44 writes theta(k)); one tick
// of lag in a slowly varying theta.
// Learning starts once u_hat(k-D) is a value produced by predict(): D ticks after
// construction or reset_history().
//
// Sign of H: H = dz(k)/du_hat(k-D) = +d y_hat/d u_hat, because z = y_hat - y. For the film
// resistance this is minus the negative-electrode pore-wall current density (the film drop
// j_n R_film enters the overpotential), so H > 0 in charge and H < 0 in discharge: set it
// per mode with set_markov_parameter() (the paper runs RCSI only in constant-current charge).
//
// Resets: reset() restores theta(0) and P(0) only (paper: at the start of every charging
// cycle); the signal history (the film resistance itself) is continuous and kept.
// reset_history() restarts the history (a different cell, power-up without a saved state).
//
// Firmware rules: fixed-size Eigen only, no heap, no exceptions, no RTTI, no globals.
#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>

#include <Eigen/Core>

#include "bms/fw/estimation/fw_status.hpp"
#include "bms/fw/estimation/rcsi_retrospective.hpp"
#include "bms/fw/estimation/rls.hpp"
#include "bms/fw/estimation/rls_arx.hpp"

namespace bms::fw {

/// The paper's RCSI settings, written once: the Markov parameter H [V per ohm m2] and the RLS
/// initial covariance P(0) = p0 I (n_c = 1, eta = 0, lambda = 1 are the Config defaults below).
inline constexpr double kPaperMarkovVPerOhmM2 = 0.01;
inline constexpr double kPaperCovarianceP0 = 5e-7;

template <typename Scalar = double, int Nc = 1, int D = 1>
class RcsiEstimator {
  static_assert(std::is_floating_point<Scalar>::value, "Scalar must be a floating-point type");
  static_assert(Nc >= 1 && Nc <= 8, "subsystem order n_c must be in 1..8");
  static_assert(D >= 0 && D <= 8, "delay d must be in 0..8");

 public:
  static constexpr int kOrder = Nc;
  static constexpr int kDelay = D;
  static constexpr int kNumRegressors = 2 * Nc;
  using RlsType = Rls<Scalar, kNumRegressors>;
  using Vector = typename RlsType::Vector;
  using Matrix = typename RlsType::Matrix;

  struct Config {
    // Markov parameter H = dz(k)/du_hat(k-D) [V/(ohm.m2)]; nonzero (paper: 0.01, D = 1).
    Scalar markov_v_per_ohm_m2 = Scalar(kPaperMarkovVPerOhmM2);
    // Retrospective regularisation eta >= 0 [V^2/(ohm.m2)^2] (paper: 0).
    Scalar eta = Scalar(0);
    // RLS forgetting factor in (0, 1].
    Scalar lambda = Scalar(1);
    // P(0) diagonal for the M (u_hat) and the N (y0_hat) regressors (paper: 5e-7 for both).
    // Different values rescale regressors of very different size (3e-3 ohm.m2 vs 10 A/m3).
    Scalar p0_u = Scalar(kPaperCovarianceP0);
    Scalar p0_y0 = Scalar(kPaperCovarianceP0);
    // trace(P) <= factor * trace(P(0)); >= 1.
    Scalar p_trace_cap_factor = Scalar(1);
    // theta(0) = [M1..MNc, N1..NNc]. Zero makes u_hat(0) = 0; [1, 0, ...] holds the film.
    Vector theta0 = Vector::Zero();
    // History before the first tick: u_hat(k) and y0_hat(k) for k < 0.
    Scalar r_film_init_ohm_m2 = Scalar(0);
    Scalar j_side_init_a_m3 = Scalar(0);
    // Admissible range of u_hat; a prediction outside it is clipped and flagged.
    Scalar r_film_min_ohm_m2 = Scalar(0);
    Scalar r_film_max_ohm_m2 = Scalar(1);
  };

  // Plain-old-data image of the whole run-time state, for non-volatile memory. No padding
  // (checked below), so byte-wise comparisons and CRCs are meaningful.
  struct State {
    std::uint32_t layout_tag;        // kLayoutTag: rejects images of another instantiation
    std::uint32_t flags;             // kFlag* below
    std::uint32_t ticks;             // committed ticks since the history reset (saturating)
    StatusWord status;               // sticky status bits
    StatusWord tick_status;          // status bits of the current tick
    std::uint32_t reserved;          // 0
    Scalar markov_v_per_ohm_m2;      // H in use (set_markov_parameter)
    Scalar u_hat_ohm_m2;             // last predicted u_hat
    Scalar u_star_ohm_m2;            // last retrospective u*, valid if kFlagUStarValid
    typename RlsType::State rls;     // theta, P
    Scalar phi_history[(D + 1) * kNumRegressors];  // phi(k-1), ..., phi(k-1-D)
  };
  static_assert(std::is_trivially_copyable<State>::value, "State must be trivially copyable");
  static_assert(std::is_standard_layout<State>::value, "State must be standard layout");
  static_assert(sizeof(State) == 6 * sizeof(std::uint32_t) +
                                     sizeof(Scalar) * (3 + kNumRegressors +
                                                       kNumRegressors * kNumRegressors +
                                                       (D + 1) * kNumRegressors),
                "State must not contain padding");

  static constexpr std::uint32_t kStateVersion = 1u;
  static constexpr std::uint32_t kLayoutTag =
      (0x52u << 24) | (kStateVersion << 16) |
      (static_cast<std::uint32_t>(sizeof(Scalar)) << 8) | (static_cast<std::uint32_t>(Nc) << 4) |
      static_cast<std::uint32_t>(D);
  static constexpr std::uint32_t kFlagPending = 1u << 0;     // predict() done, update() due
  static constexpr std::uint32_t kFlagUStarValid = 1u << 1;  // u* computed in this tick
  static constexpr std::uint32_t kFlagThetaUpdated = 1u << 2;  // RLS step accepted this tick

  explicit RcsiEstimator(const Config& config)
      : config_(config), config_ok_(validate(config)), rls_(make_rls_config(config)) {
    markov_ = config_ok_ ? config.markov_v_per_ohm_m2 : Scalar(1);
    const Scalar r0 = config_ok_ ? config.r_film_init_ohm_m2 : Scalar(0);
    const Scalar j0 = config_ok_ ? config.j_side_init_a_m3 : Scalar(0);
    fill_history(r0, j0);
    if (!config_ok_) {
      raise(FwStatus::kConfigInvalid);
    }
  }

  static bool validate(const Config& c) {
    const bool finite = std::isfinite(c.markov_v_per_ohm_m2) && std::isfinite(c.eta) &&
                        std::isfinite(c.r_film_init_ohm_m2) && std::isfinite(c.j_side_init_a_m3) &&
                        std::isfinite(c.r_film_min_ohm_m2) && std::isfinite(c.r_film_max_ohm_m2);
    return finite && c.markov_v_per_ohm_m2 != Scalar(0) && c.eta >= Scalar(0) &&
           c.r_film_min_ohm_m2 <= c.r_film_max_ohm_m2 &&
           c.r_film_init_ohm_m2 >= c.r_film_min_ohm_m2 &&
           c.r_film_init_ohm_m2 <= c.r_film_max_ohm_m2 && RlsType::validate(make_rls_config(c));
  }

  // Restores theta(0) and P(0) (paper: at the start of each charging cycle). The signal
  // history, H and the status words are kept.
  void reset() { rls_.reset(); }

  // Restarts the signal history as if u_hat and y0_hat had been constant before now.
  // Learning resumes D ticks later. Returns false (nothing changed) on non-finite or
  // out-of-range values.
  bool reset_history(Scalar r_film_ohm_m2, Scalar j_side_a_m3) {
    if (!std::isfinite(r_film_ohm_m2) || !std::isfinite(j_side_a_m3) || !in_range(r_film_ohm_m2)) {
      raise(FwStatus::kConfigInvalid);
      return false;
    }
    fill_history(r_film_ohm_m2, j_side_a_m3);
    return true;
  }

  // Tick step 5: u_hat(k) = theta^T phi(k-1), clipped to [min, max] (kOutputClipped).
  // A non-finite product (overflow) holds u_hat(k-1) (kPredictionNonFinite). Calling it
  // twice before update() returns the same value.
  Scalar predict() {
    tick_status_ = 0u;
    const Scalar held = phi_history_[0](0);  // u_hat(k-1), always finite and in range
    Scalar u = rls_.predict(phi_history_[0]);
    if (!config_ok_) {
      u = held;
      raise(FwStatus::kConfigInvalid);
    } else if (!std::isfinite(u)) {
      u = held;
      raise(FwStatus::kPredictionNonFinite);
    } else if (u < config_.r_film_min_ohm_m2) {
      u = config_.r_film_min_ohm_m2;
      raise(FwStatus::kOutputClipped);
    } else if (u > config_.r_film_max_ohm_m2) {
      u = config_.r_film_max_ohm_m2;
      raise(FwStatus::kOutputClipped);
    }
    u_hat_ = u;
    pending_ = true;
    u_star_valid_ = false;
    theta_updated_ = false;
    return u;
  }

  // Tick step 9: z(k) = y_hat(k) - y(k) [V] and the model's y0_hat(k) [A/m3].
  // Learns from u*(k-D) unless an input is non-finite (kRejectedNonFinite: theta and P
  // unchanged), then commits u_hat(k) and y0_hat(k) to the history (a non-finite y0_hat is
  // replaced by y0_hat(k-1)). Time always advances: the model has used u_hat(k).
  // Returns the status bits raised in this tick (predict() and update()).
  StatusWord update(Scalar z_v, Scalar j_side_a_m3) { return commit(z_v, j_side_a_m3, true); }

  // Tick step 9 when learning is off (e.g. outside constant-current charging, where
  // the film is not identifiable): commits u_hat(k) and y0_hat(k) without learning.
  StatusWord advance_without_learning(Scalar j_side_a_m3) {
    return commit(Scalar(0), j_side_a_m3, false);
  }

  // Sets H (e.g. when the current direction flips). Rejects 0 and non-finite values.
  bool set_markov_parameter(Scalar h_v_per_ohm_m2) {
    if (!std::isfinite(h_v_per_ohm_m2) || h_v_per_ohm_m2 == Scalar(0)) {
      raise(FwStatus::kConfigInvalid);
      return false;
    }
    markov_ = h_v_per_ohm_m2;
    return true;
  }

  const Vector& theta() const { return rls_.theta(); }
  const Matrix& p() const { return rls_.p(); }
  // Last predicted u_hat (before the first predict(): the initial history value).
  Scalar u_hat_ohm_m2() const { return u_hat_; }
  // Retrospective u*(k-D) of the current tick; quiet NaN if none was computed.
  Scalar u_star_ohm_m2() const {
    return u_star_valid_ ? u_star_ : std::numeric_limits<Scalar>::quiet_NaN();
  }
  // True if the current tick's update() changed theta and P (an accepted RLS step), e.g. for
  // an "RCSI active" flag on the bus.
  bool theta_updated() const { return theta_updated_; }
  // phi(k-1): the regressor the next predict() will use (after update()) or used.
  const Vector& regressor() const { return phi_history_[0]; }
  Scalar markov_parameter() const { return markov_; }
  bool config_ok() const { return config_ok_; }
  const Config& config() const { return config_; }
  // Sticky status (OR of all bits since construction or clear_status()).
  StatusWord status() const { return status_; }
  // Bits raised since the last predict().
  StatusWord tick_status() const { return tick_status_; }
  void clear_status() { status_ = 0u; }

  State save() const {
    State s{};
    s.layout_tag = kLayoutTag;
    s.flags = (pending_ ? kFlagPending : 0u) | (u_star_valid_ ? kFlagUStarValid : 0u) |
              (theta_updated_ ? kFlagThetaUpdated : 0u);
    s.ticks = ticks_;
    s.status = status_;
    s.tick_status = tick_status_;
    s.reserved = 0u;
    s.markov_v_per_ohm_m2 = markov_;
    s.u_hat_ohm_m2 = u_hat_;
    s.u_star_ohm_m2 = u_star_;
    s.rls = rls_.save();
    for (int j = 0; j <= D; ++j) {
      Eigen::Map<Vector>(s.phi_history + j * kNumRegressors) = phi_history_[j];
    }
    return s;
  }

  // Restores a saved image. Rejects (returns false, changes nothing but the sticky
  // kConfigInvalid bit) images of another layout or with invalid content.
  bool restore(const State& s) {
    bool ok = s.layout_tag == kLayoutTag && s.reserved == 0u &&
              (s.flags & ~(kFlagPending | kFlagUStarValid | kFlagThetaUpdated)) == 0u &&
              std::isfinite(s.markov_v_per_ohm_m2) && s.markov_v_per_ohm_m2 != Scalar(0) &&
              std::isfinite(s.u_star_ohm_m2) && in_range(s.u_hat_ohm_m2);
    for (int j = 0; ok && j <= D; ++j) {
      const Eigen::Map<const Vector> phi(s.phi_history + j * kNumRegressors);
      ok = phi.allFinite();
      for (int i = 0; ok && i < Nc; ++i) {
        ok = in_range(phi(i));
      }
    }
    RlsType candidate = rls_;
    ok = ok && candidate.restore(s.rls);
    if (!ok) {
      raise(FwStatus::kConfigInvalid);
      return false;
    }
    rls_ = candidate;
    pending_ = (s.flags & kFlagPending) != 0u;
    u_star_valid_ = (s.flags & kFlagUStarValid) != 0u;
    theta_updated_ = (s.flags & kFlagThetaUpdated) != 0u;
    ticks_ = s.ticks;
    status_ = s.status;
    tick_status_ = s.tick_status;
    markov_ = s.markov_v_per_ohm_m2;
    u_hat_ = s.u_hat_ohm_m2;
    u_star_ = s.u_star_ohm_m2;
    for (int j = 0; j <= D; ++j) {
      phi_history_[j] = Eigen::Map<const Vector>(s.phi_history + j * kNumRegressors);
    }
    return true;
  }

 private:
  static constexpr StatusWord kRlsRejectMask = bit(FwStatus::kRejectedNonFinite) |
                                               bit(FwStatus::kThetaRestored) |
                                               bit(FwStatus::kConfigInvalid);

  static typename RlsType::Config make_rls_config(const Config& c) {
    typename RlsType::Config rc;
    rc.lambda = c.lambda;
    rc.p0_diag.template head<Nc>().setConstant(c.p0_u);
    rc.p0_diag.template tail<Nc>().setConstant(c.p0_y0);
    rc.theta0 = c.theta0;
    rc.p_trace_cap_factor = c.p_trace_cap_factor;
    return rc;
  }

  bool in_range(Scalar r_film_ohm_m2) const {
    return r_film_ohm_m2 >= config_.r_film_min_ohm_m2 &&
           r_film_ohm_m2 <= config_.r_film_max_ohm_m2;
  }

  void fill_history(Scalar r_film_ohm_m2, Scalar j_side_a_m3) {
    for (int j = 0; j <= D; ++j) {
      phi_history_[j].template head<Nc>().setConstant(r_film_ohm_m2);
      phi_history_[j].template tail<Nc>().setConstant(j_side_a_m3);
    }
    u_hat_ = r_film_ohm_m2;
    u_star_ = Scalar(0);
    u_star_valid_ = false;
    theta_updated_ = false;
    pending_ = false;
    ticks_ = 0u;
  }

  void raise(FwStatus s) {
    tick_status_ |= bit(s);
    status_ |= bit(s);
  }
  void raise_word(StatusWord w) {
    tick_status_ |= w;
    status_ |= w;
  }

  // u_hat(k-D): the applied value the current z first depends on.
  Scalar applied_u_delayed() const {
    if constexpr (D == 0) {
      return u_hat_;
    } else {
      return phi_history_[D - 1](0);
    }
  }

  StatusWord commit(Scalar z_v, Scalar j_side_a_m3, bool learn) {
    if (!pending_) {
      raise(FwStatus::kCallOrder);
      return tick_status_;
    }
    const bool j_finite = std::isfinite(j_side_a_m3);
    if (!config_ok_) {
      raise(FwStatus::kConfigInvalid);
    } else if (!j_finite || (learn && !std::isfinite(z_v))) {
      raise(FwStatus::kRejectedNonFinite);
    } else if (learn && ticks_ >= static_cast<std::uint32_t>(D)) {
      const Scalar u_star =
          rcsi_retrospective_u_star(applied_u_delayed(), z_v, markov_, config_.eta);
      if (std::isfinite(u_star)) {
        u_star_ = u_star;
        u_star_valid_ = true;
        // phi_history_[D] = phi(k-D-1): the regressor that produced u_hat(k-D).
        const StatusWord rls_status = rls_.update(phi_history_[D], u_star);
        raise_word(rls_status);
        theta_updated_ = (rls_status & kRlsRejectMask) == 0u;
      } else {
        raise(FwStatus::kRejectedNonFinite);
      }
    }
    // Advance time: phi(k-1) -> phi(k) with u_hat(k) and y0_hat(k).
    const Scalar j_store = j_finite ? j_side_a_m3 : phi_history_[0](Nc);
    for (int j = D; j > 0; --j) {
      phi_history_[j] = phi_history_[j - 1];
    }
    rls_arx_push<Scalar, Nc>(phi_history_[0], u_hat_, j_store);
    if (ticks_ < std::numeric_limits<std::uint32_t>::max()) {
      ++ticks_;
    }
    pending_ = false;
    return tick_status_;
  }

  Config config_;
  bool config_ok_;
  RlsType rls_;
  Scalar markov_ = Scalar(1);
  Vector phi_history_[D + 1];  // phi_history_[j] = phi(k-1-j) during tick k
  Scalar u_hat_ = Scalar(0);
  Scalar u_star_ = Scalar(0);
  bool u_star_valid_ = false;
  bool theta_updated_ = false;
  bool pending_ = false;
  std::uint32_t ticks_ = 0u;
  StatusWord status_ = 0u;
  StatusWord tick_status_ = 0u;
};

}  // namespace bms::fw
