#pragma once
// State re-synchronisation (beyond the paper; tick step 7, and its power-up start in step 2):
// the model's state is moved to a straight line fitted to a window of measured voltage and
// current (ResyncWindow) at the nominal, or identified, lithium inventory minus the model's own
// loss (MainModel::resync, called by BmsCore). Removes initial-condition errors and the model's
// drift before the next CC phase.
//
// Conditions, in the style of an aid source:
//   should_start_at_power_up  the first accepted sample with no restored state (a BMS wakes
//                    from rest: uniform particles), before a discharge can clip the particle
//                    profiles at the stoichiometry limits, which a later uniform shift cannot repair;
//                    under a current (|I| above Config::current_a at that sample) only once
//                    settle_s of samples have passed (follow_power_up): in the first seconds
//                    under load the cell's voltage and the model's differ by tens of mV (their
//                    electrolyte and particle surfaces start from rest differently: About:Energy
//                    at 0.84C, 43 mV at the first sample, under 1 mV after 6 s), and the window
//                    would read that as state of charge (on About:Energy's flat LFP curve it
//                    moved the model to its empty end);
//   should_start_at_cv_end    once per CV phase, when |I| has fallen to Config::current_a;
//   should_continue  a window is open: each accepted sample is added; collect() says when it
//                    is full and the model is to be re-synchronised;
//   should_stop      the model left the voltage-driven phase: a CV window that did not fill is
//                    dropped (the power-up window stays open until it fills).
// Header-only C++17: no heap, no exceptions, no RTTI.
#include <cmath>
#include <cstdint>

#include "bms/fw/estimation/resync_window.hpp"

namespace bms::fw {

template <typename Scalar>
class StateResync {
 public:
  struct Config {
    bool at_start = false;
    bool at_cv_end = false;
    Scalar current_a = Scalar(0.25);  // |I| at which a CV phase's window opens
    std::uint32_t window_ticks = 1u;  // 1 = the trigger sample alone
    Scalar settle_s = Scalar(0);      // the power-up window under a current opens after this [s]
  };

  // Trivially copyable, for the NVM image.
  struct State {
    typename ResyncWindow<Scalar>::State window;
    Scalar inventory_deviation_model;  // of the model's last re-synchronisation
    std::uint32_t count;
    std::uint32_t flags;  // bit 0: re-synchronised in this CV phase, bit 1: the open window is the power-up one
  };
  using Fit = typename ResyncWindow<Scalar>::Fit;

  explicit StateResync(const Config& config) : c_(config) {}

  bool should_start_at_power_up(bool first_sample) const { return c_.at_start && first_sample; }
  // Each accepted sample. A power-up (first_sample) at rest (|I| <= Config::current_a: the BMS
  // woke from rest) opens its window at once; one under a current is pending until settle_s of
  // samples have passed, whatever the current does meanwhile (a drive cycle's zero crossings are
  // not rest). A restored state has no power-up; a pending one is not saved (a restore within
  // settle_s has none either).
  void follow_power_up(bool first_sample, Scalar current_a, Scalar dt_s) {
    if (should_start_at_power_up(first_sample)) {
      if (std::fabs(current_a) <= c_.current_a) {
        power_up_pending_ = false;
        start_at_power_up();
        return;
      }
      power_up_pending_ = true;
      power_up_elapsed_s_ = Scalar(0);
    }
    if (!power_up_pending_) return;
    power_up_elapsed_s_ += dt_s;
    if (power_up_elapsed_s_ >= c_.settle_s) {
      power_up_pending_ = false;
      start_at_power_up();
    }
  }
  void start_at_power_up() {
    window_.open(c_.window_ticks);
    power_up_window_ = true;
  }
  bool should_stop(bool voltage_driven) const { return !voltage_driven; }
  bool should_start_at_cv_end(bool voltage_driven, Scalar current_a) const {
    return c_.at_cv_end && voltage_driven && !done_in_phase_ && !window_.is_open() &&
           std::fabs(current_a) <= c_.current_a;
  }
  bool should_continue() const { return window_.is_open(); }

  // Stop or start by this tick's phase (after the model step: the phase is the model's drive).
  void follow_phase(bool voltage_driven, Scalar current_a) {
    if (should_stop(voltage_driven)) {
      done_in_phase_ = false;
      if (!power_up_window_) window_.close();  // the CV phase ended before its window filled
    } else if (should_start_at_cv_end(voltage_driven, current_a)) {
      done_in_phase_ = true;
      window_.open(c_.window_ticks);
      power_up_window_ = false;
    }
  }

  // Adds the sample to the open window; true (and `fit` set, the window closed) when it is full.
  bool collect(Scalar voltage_v, Scalar current_a, Fit& fit) {
    if (!should_continue()) return false;
    window_.add(voltage_v, current_a);
    if (!window_.full()) return false;
    fit = window_.fit();
    window_.close();
    power_up_window_ = false;
    return true;
  }

  // The model took the re-synchronisation to inventory deviation nu; true when that moved the
  // model's inventory by more than relinearise_limit since the last one.
  bool succeeded(Scalar nu, Scalar relinearise_limit) {
    ++count_;
    const bool moved = std::fabs(nu - nu_model_) > relinearise_limit;
    nu_model_ = nu;
    return moved;
  }

  std::uint32_t count() const { return count_; }
  // The open window is the power-up one (not a CV end).
  bool power_up_window() const { return power_up_window_; }
  Scalar inventory_deviation_model() const { return nu_model_; }

  State save() const {
    return State{window_.state(), nu_model_, count_, (done_in_phase_ ? 1u : 0u) | (power_up_window_ ? 2u : 0u)};
  }
  // The inventory deviation within +-nu_max (the identifier's limit).
  bool restore(const State& s, Scalar nu_max) {
    ResyncWindow<Scalar> w;
    const bool nu_ok = std::isfinite(s.inventory_deviation_model) && s.inventory_deviation_model >= -nu_max &&
                       s.inventory_deviation_model <= nu_max;
    if (!nu_ok || (s.flags & ~3u) != 0u || !w.restore(s.window)) return false;
    window_ = w;
    nu_model_ = s.inventory_deviation_model;
    count_ = s.count;
    done_in_phase_ = (s.flags & 1u) != 0u;
    power_up_window_ = (s.flags & 2u) != 0u;
    return true;
  }

 private:
  Config c_;
  ResyncWindow<Scalar> window_;
  Scalar nu_model_ = Scalar(0);
  std::uint32_t count_ = 0u;
  bool done_in_phase_ = false;
  bool power_up_window_ = false;
  bool power_up_pending_ = false;
  Scalar power_up_elapsed_s_ = Scalar(0);
};

}  // namespace bms::fw
