#pragma once
// When the film is learned (tick steps 4 and 9): RCSI, or the FilmGrowthIdentifier of the
// `best` profile, learns only in a constant-current charge (elsewhere the film is not
// identifiable), after a warm-up (the first seconds after a deep CV discharge are where the
// reduced model is least accurate: a reaction front it cannot hold), and once the voltage bias
// is known (BiasCalibration::blocks_learning). The film is held outside that window.
//
// Conditions, in the style of an aid source:
//   should_open      start and continue: CC charge, warm, bias ready;
//   should_start     the window opens in this tick: RCSI's theta and P are reset (paper) and its
//                    history restarts from the film held so far; H is taken from the model
//                    (should_take_markov_from_model);
//   phase_ended      the CC charge ended (the bias calibration's stop);
//   should_identify  the identifier learns: the window is open, learning is on and the model is
//                    current-driven; should_start_identifying: first such tick of a charge.
// Header-only C++17: no heap, no exceptions, no RTTI.
#include <cstdint>

namespace bms::fw {

template <typename Scalar>
class LearningGate {
 public:
  struct Config {
    Scalar warmup_s = Scalar(0);
    Scalar dt_s = Scalar(0.2);
    bool learning = true;          // false: the control run, every RCSI / RLS update off
    bool identify_growth = false;  // the FilmGrowthIdentifier learns instead of RCSI
    // Paper: constant H. When true, H = dV/dR_film of the model at the window's start.
    bool markov_from_model = false;
  };

  // Trivially copyable, for the NVM image.
  struct State {
    std::uint32_t cc_ticks;
    std::uint32_t flags;  // bit 0: the window was open in the previous tick, bit 1: the identifier learned in it
  };

  explicit LearningGate(const Config& config) : c_(config) {}

  bool phase_ended(bool in_cc_charge) const { return !in_cc_charge && cc_ticks_ > 0u; }
  void count_phase(bool in_cc_charge) {
    cc_ticks_ = in_cc_charge ? (cc_ticks_ < 0xFFFFFFFFu ? cc_ticks_ + 1u : cc_ticks_) : 0u;
  }
  bool warm() const { return static_cast<Scalar>(cc_ticks_) * c_.dt_s > c_.warmup_s; }
  bool should_open(bool in_cc_charge, bool bias_ready) const { return in_cc_charge && warm() && bias_ready; }
  bool should_start(bool open) const { return open && !was_open_; }
  bool should_take_markov_from_model(bool open) const { return c_.markov_from_model && should_start(open); }
  void close_tick(bool open) { was_open_ = open; }

  bool identifies() const { return c_.identify_growth; }
  bool learning() const { return c_.learning; }
  bool should_identify(bool open, bool voltage_driven) const {
    return c_.identify_growth && c_.learning && open && !voltage_driven;
  }
  bool should_start_identifying(bool identify) const { return identify && !was_identifying_; }
  void identified(bool identify) { was_identifying_ = identify; }

  State save() const { return State{cc_ticks_, (was_open_ ? 1u : 0u) | (was_identifying_ ? 2u : 0u)}; }
  bool restore(const State& s) {
    if ((s.flags & ~3u) != 0u) return false;
    cc_ticks_ = s.cc_ticks;
    was_open_ = (s.flags & 1u) != 0u;
    was_identifying_ = (s.flags & 2u) != 0u;
    return true;
  }

 private:
  Config c_;
  std::uint32_t cc_ticks_ = 0u;
  bool was_open_ = false;
  bool was_identifying_ = false;
};

}  // namespace bms::fw
