#pragma once
// Operating-mode detection from the measured current and voltage, with debouncing.
//
// A sample is classified by sign and size of the current and by the voltage's distance to
// the charge/discharge limits:
//   |I| < rest_current_a                                   -> rest
//   I < 0 (charge):    V >= v_max - cv_band_v and |I| below the CC level -> cv_charge,
//                      otherwise                                         -> cc_charge
//   I > 0 (discharge): V <= v_min + cv_band_v and |I| below the CC level -> cv_discharge,
//                      otherwise                                         -> cc_discharge
// "Below the CC level" means |I| < |I_cc| - cc_tolerance_a, where I_cc is the current seen
// when the present constant-current phase was confirmed; without a CC level (e.g. power-up
// in CV) the voltage band alone decides. A different mode is reported only after it has been the
// raw class for debounce_ticks consecutive ticks, so noise near a threshold cannot toggle
// the estimator on and off.
#include <cmath>
#include <cstdint>
#include <type_traits>

#include "bms/fw/estimation/operating_mode.hpp"

namespace bms::fw {

template <typename Scalar = double>
class ModeDetector {
 public:
  struct Config {
    Scalar rest_current_a = Scalar(0.05);   // below the CV end current (0.125 A) of the paper protocol
    Scalar cc_tolerance_a = Scalar(0.03);   // 6 sigma of the paper's largest current noise (5 mA)
    Scalar cv_band_v = Scalar(0.005);       // 25 sigma of the paper's largest voltage noise (0.2 mV)
    Scalar v_max = Scalar(3.6);
    Scalar v_min = Scalar(2.0);
    std::uint16_t debounce_ticks = 5;       // 1 s at 0.2 s ticks
  };

  struct State {
    std::uint8_t mode;        // Mode
    std::uint8_t candidate;   // Mode
    std::uint16_t candidate_ticks;
    std::uint32_t reserved;
    Scalar cc_level_a;        // |I| of the confirmed CC phase; 0 = none
  };
  static_assert(std::is_trivially_copyable<State>::value, "State must be trivially copyable");

  ModeDetector() : ModeDetector(Config{}) {}
  explicit ModeDetector(const Config& c) : config_(c) { reset(); }

  void reset() {
    s_ = State{};
    s_.mode = static_cast<std::uint8_t>(Mode::unknown);
    s_.candidate = static_cast<std::uint8_t>(Mode::unknown);
    s_.cc_level_a = Scalar(0);
  }

  // Classifies one sample (inputs must be finite: the caller validates them) and returns the
  // debounced mode.
  Mode update(Scalar voltage_v, Scalar current_a) {
    const Mode raw = classify(voltage_v, current_a);
    raw_ = raw;
    if (raw == mode()) {
      s_.candidate = s_.mode;
      s_.candidate_ticks = 0;
    } else {
      if (static_cast<std::uint8_t>(raw) != s_.candidate) {
        s_.candidate = static_cast<std::uint8_t>(raw);
        s_.candidate_ticks = 0;
      }
      if (++s_.candidate_ticks >= config_.debounce_ticks) {
        s_.mode = s_.candidate;
        s_.candidate_ticks = 0;
        const Mode m = mode();
        s_.cc_level_a = (m == Mode::cc_charge || m == Mode::cc_discharge) ? std::fabs(current_a)
                        : (m == Mode::rest ? Scalar(0) : s_.cc_level_a);
      }
    }
    return mode();
  }

  Mode mode() const { return static_cast<Mode>(s_.mode); }
  // This tick's undebounced class: decides how the model is driven (a model driven by a
  // stale CV class would be forced to a voltage that belongs to the next phase).
  Mode raw_mode() const { return raw_; }
  const State& state() const { return s_; }
  bool restore(const State& s) {
    if (s.mode > static_cast<std::uint8_t>(Mode::unknown) || s.candidate > static_cast<std::uint8_t>(Mode::unknown) ||
        !std::isfinite(s.cc_level_a) || s.cc_level_a < Scalar(0)) {
      return false;
    }
    s_ = s;
    return true;
  }
  const Config& config() const { return config_; }

 private:
  Mode classify(Scalar v, Scalar i) const {
    const Scalar mag = std::fabs(i);
    if (mag < config_.rest_current_a) return Mode::rest;
    const bool below_cc = s_.cc_level_a <= Scalar(0) || mag < s_.cc_level_a - config_.cc_tolerance_a;
    if (i < Scalar(0)) {
      return (v >= config_.v_max - config_.cv_band_v && below_cc) ? Mode::cv_charge : Mode::cc_charge;
    }
    return (v <= config_.v_min + config_.cv_band_v && below_cc) ? Mode::cv_discharge : Mode::cc_discharge;
  }

  Config config_;
  State s_{};
  Mode raw_ = Mode::unknown;
};

}  // namespace bms::fw
