#pragma once
// Bias calibration (beyond the paper; tick step 8): the first CC charge after the warm-up is a
// reference charge at the known initial film resistance, and the mean residual z over it is
// stored as the model's voltage bias, subtracted from z in every later charge. In CC a constant
// bias is collinear with R_film and would otherwise be read as film resistance.
//
// Conditions, in the style of an aid source:
//   should_collect   start and continue: CC charge, warm, not yet calibrated, and the state
//                    re-synchronised often enough (a model started from a wrong state leaves the
//                    first discharge with clipped particle profiles: 0.3 mV in the first charge);
//   stop_at_charge_end  the charge ended: the bias is taken when long_enough(), else the
//                    samples are dropped and the next charge is the reference instead;
//   blocks_learning  RCSI waits until the bias is known (the film is held meanwhile).
// Header-only C++17: no heap, no exceptions, no RTTI.
#include <cmath>
#include <cstdint>

namespace bms::fw {

template <typename Scalar>
class BiasCalibration {
 public:
  struct Config {
    bool enabled = false;
    std::uint32_t after_resyncs = 0u;     // re-synchronisations before the reference charge
    Scalar min_reference_s = Scalar(60);  // a shorter reference charge does not count
    Scalar dt_s = Scalar(0.2);
  };

  // Trivially copyable, for the NVM image.
  struct State {
    Scalar sum_v;
    Scalar bias_v;
    std::uint32_t samples;
    std::uint32_t calibrated;  // 0 or 1
  };

  // Largest bias an image may hold (the reduced model's bias is about a millivolt).
  static constexpr double kMaxBias_v = 1.0;

  explicit BiasCalibration(const Config& config) : c_(config) {}

  bool blocks_learning() const { return c_.enabled && !calibrated_; }
  bool should_collect(bool in_cc_charge, bool warm, std::uint32_t resync_count) const {
    return in_cc_charge && warm && c_.enabled && !calibrated_ && resync_count >= c_.after_resyncs;
  }
  void collect(Scalar z_v) {
    sum_v_ += z_v;
    ++samples_;
  }
  bool long_enough() const { return static_cast<Scalar>(samples_) * c_.dt_s >= c_.min_reference_s; }
  void stop_at_charge_end() {
    if (!c_.enabled || calibrated_) return;
    if (long_enough()) {
      bias_v_ = sum_v_ / static_cast<Scalar>(samples_);
      calibrated_ = true;
    }
    sum_v_ = Scalar(0);
    samples_ = 0u;
  }
  Scalar corrected(Scalar z_v) const { return calibrated_ ? z_v - bias_v_ : z_v; }

  bool calibrated() const { return calibrated_; }
  Scalar bias_v() const { return bias_v_; }

  State save() const { return State{sum_v_, bias_v_, samples_, calibrated_ ? 1u : 0u}; }
  // The bias within kMaxBias_v and the sum within its sample count times that.
  bool restore(const State& s) {
    const Scalar lim = Scalar(kMaxBias_v);
    const Scalar sum_lim = lim * static_cast<Scalar>(s.samples);
    if (!within(s.bias_v, -lim, lim) || !within(s.sum_v, -sum_lim, sum_lim) || s.calibrated > 1u) return false;
    sum_v_ = s.sum_v;
    bias_v_ = s.bias_v;
    samples_ = s.samples;
    calibrated_ = s.calibrated != 0u;
    return true;
  }

 private:
  static bool within(Scalar v, Scalar lo, Scalar hi) { return std::isfinite(v) && v >= lo && v <= hi; }

  Config c_;
  Scalar sum_v_ = Scalar(0);
  Scalar bias_v_ = Scalar(0);
  std::uint32_t samples_ = 0u;
  bool calibrated_ = false;
};

}  // namespace bms::fw
