#pragma once
// The voltage sensor's offset (beyond the paper; tick steps 2 and 9). A BMS front end's voltage
// sensor reads the cell's voltage plus an offset of some tenths of a millivolt. In CC charge a
// constant offset is collinear with the film's I R drop: the identifier reads it as film (measured
// on the paper cell about 30 % of the film per mV at 1C).
//
// Across operating points they are not collinear. The film's drop changes sign with the current,
// the offset does not. Once a CC charge has been fitted, the film in use carries the offset as
// dR = b / H_c (H_c = dV/dR_film at the charge's learning ticks), and a CC discharge that follows
// shows the residual z = y_hat - y = H_d dR - b = -(1 - H_d / H_c) b, where H_d is the discharge's
// (about -H_c at the same current: z is about -2 b). So the remaining offset is
//   b = -sum z / sum (1 - H_d / H_c)
// over the discharge's ticks, with z corrected for the model's design-time bias (the same
// resistance-like bias the identifier removes in charge: on the nominal paper cell the corrected
// discharge residual is within 0.03 mV of zero after the first cycle). It needs only the measured
// voltage and current, and the model's H.
//
// Conditions, in the style of an aid source:
//   armed           at least Config::min_fitted_ticks learning ticks since the offset in use last
//                   changed (a charge fitted on the voltage as now corrected), and the film path not
//                   holding a restarted fit (BmsCore passes it each tick);
//   collect         in CC discharge (the model current-driven), after Config::warmup_s in the
//                   phase (the reduced model's error settles, as in charge), while armed;
//   fuse            at the end of that CC discharge, when at least Config::min_ticks were
//                   collected and |b| <= Config::limit_v (larger is not a front end's offset:
//                   the model does not fit the cell, nothing is corrected);
//   continue        a fused b outside the dead band (Config::deadband_v) is added to the offset in
//                   use, subtracted from every later sample's voltage; the film path forgets what
//                   it learned on the old voltage (BmsCore::follow_voltage_offset), as at a current
//                   offset's change; a b inside the dead band changes nothing;
//   stop            a power cycle or a gap over Config::max_gap_s drops the phase's sums.
// Header-only C++17: no heap, no exceptions, no RTTI.
#include <cmath>
#include <cstdint>
#include <limits>

namespace bms::fw {

template <typename Scalar>
class VoltageOffset {
 public:
  struct Config {
    bool enabled = false;
    Scalar warmup_s = Scalar(900);          // into the CC discharge before its residual counts
    std::uint32_t min_ticks = 1500u;        // 5 minutes of 0.2 s ticks collected
    std::uint32_t min_fitted_ticks = 3000u; // 10 minutes of charge learned since the last change
    Scalar limit_v = Scalar(0.005);         // the largest offset a front end's sensor has
    // A smaller remainder is not corrected: the bias-corrected discharge residual of the paper cell
    // with no offset gives |b| <= 0.03 mV (cycles 2-5, seeds 1-2, the envelope truth).
    Scalar deadband_v = Scalar(0.0001);
    Scalar model_bias_ohm = Scalar(0);      // the film path's design-time bias (resistance-like)
    Scalar dt_s = Scalar(0.2);
    Scalar max_gap_s = Scalar(0.5);
  };

  // Trivially copyable, for the NVM image.
  struct State {
    double sum_z_v;               // bias-corrected residual summed over the phase's collected ticks
    double sum_w;                 // (1 - H_d / H_c) summed over the same ticks
    Scalar offset_v;              // in use
    Scalar charge_markov_v_per_ohm_m2;  // H_c of the last learning tick
    Scalar phase_s;               // time in the current CC discharge
    std::uint32_t ticks;          // collected in this phase
    std::uint32_t fitted_ticks;   // learning ticks since the offset in use last changed
    std::uint32_t fused;          // discharges fused so far
    std::uint32_t flags;          // bit 0: in a CC discharge
  };

  explicit VoltageOffset(const Config& config) : c_(config) {}

  // The voltage the model and the estimator see.
  Scalar corrected(Scalar measured_v) const { return measured_v - offset_v(); }
  Scalar offset_v() const { return c_.enabled ? s_.offset_v : Scalar(0); }
  std::uint32_t fused() const { return s_.fused; }
  // The last fused discharge's remainder (NaN before any).
  Scalar last_remainder_v() const { return last_remainder_v_; }
  const Config& config() const { return c_; }

  // Step 2: a power cycle or a long gap drops the phase's sums.
  void gap(std::uint32_t missed, bool power_cycle) {
    if (power_cycle || static_cast<Scalar>(missed) * c_.dt_s > c_.max_gap_s) drop_phase();
  }

  // Step 9: one tick. learned: the identifier learned in this tick (a CC charge). Returns true when
  // the offset in use changed (the film path is to forget).
  bool follow(bool cc_discharge, bool holding, bool learned, Scalar z_v, Scalar current_a, Scalar markov_v_per_ohm_m2) {
    if (!c_.enabled) return false;
    if (learned && std::isfinite(markov_v_per_ohm_m2) && markov_v_per_ohm_m2 != Scalar(0)) {
      s_.charge_markov_v_per_ohm_m2 = markov_v_per_ohm_m2;
      if (s_.fitted_ticks < 0xFFFFFFFFu) ++s_.fitted_ticks;
    }
    const bool in_phase = (s_.flags & 1u) != 0u;
    if (!cc_discharge) return in_phase && end_phase();
    if (!in_phase) drop_phase();
    s_.flags |= 1u;
    s_.phase_s += c_.dt_s;
    if (should_collect(holding)) collect(z_v, current_a, markov_v_per_ohm_m2);
    return false;
  }

  bool armed(bool holding) const {
    return c_.enabled && !holding && s_.fitted_ticks >= c_.min_fitted_ticks && s_.charge_markov_v_per_ohm_m2 != Scalar(0);
  }

  State save() const { return s_; }

  // Every value finite, the offset within +-limit_v, the flags known.
  bool restore(const State& s) {
    const bool ok = (s.flags & ~1u) == 0u && std::isfinite(s.sum_z_v) && std::isfinite(s.sum_w) &&
                    std::isfinite(s.offset_v) && std::fabs(s.offset_v) <= c_.limit_v &&
                    std::isfinite(s.charge_markov_v_per_ohm_m2) && std::isfinite(s.phase_s) && s.phase_s >= Scalar(0);
    if (!ok) return false;
    s_ = s;
    return true;
  }

 private:
  bool should_collect(bool holding) const { return armed(holding) && s_.phase_s > c_.warmup_s; }

  void collect(Scalar z_v, Scalar current_a, Scalar markov_v_per_ohm_m2) {
    const Scalar w = Scalar(1) - markov_v_per_ohm_m2 / s_.charge_markov_v_per_ohm_m2;
    const Scalar z = z_v + c_.model_bias_ohm * current_a;
    if (!std::isfinite(w) || !std::isfinite(z) || !(w > Scalar(0))) return;
    s_.sum_z_v += static_cast<double>(z);
    s_.sum_w += static_cast<double>(w);
    ++s_.ticks;
  }

  // The CC discharge ended: fuse its remainder when it is a front end's offset and outside the band.
  bool end_phase() {
    const bool enough = s_.ticks >= c_.min_ticks && s_.sum_w > 0.0;
    const Scalar b = enough ? static_cast<Scalar>(-s_.sum_z_v / s_.sum_w) : Scalar(0);
    drop_phase();
    if (!enough || !std::isfinite(b)) return false;
    last_remainder_v_ = b;
    const Scalar next = s_.offset_v + b;
    if (std::fabs(b) <= c_.deadband_v || std::fabs(next) > c_.limit_v) return false;
    s_.offset_v = next;
    s_.fitted_ticks = 0u;
    ++s_.fused;
    return true;
  }

  void drop_phase() {
    s_.sum_z_v = 0.0;
    s_.sum_w = 0.0;
    s_.phase_s = Scalar(0);
    s_.ticks = 0u;
    s_.flags &= ~1u;
  }

  Config c_;
  State s_{};
  Scalar last_remainder_v_ = std::numeric_limits<Scalar>::quiet_NaN();
};

}  // namespace bms::fw
