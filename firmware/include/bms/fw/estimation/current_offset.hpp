#pragma once
// The current sensor's offset (beyond the paper; tick steps 2 and 7). A BMS front end's current
// sensor reads the cell's current plus an offset of some milliamperes. Counted over a cycle it
// moves the model's charge by tens of mAh, which the identifier reads as lithium inventory and
// film (measured: 10 mA took the inventory 0.5 % off and the film 1.5-4.5 %).
//
// The cell tells the offset between two voltage-held end points of the same kind: the n-th and
// the (n+1)-th time a CV phase at the same voltage has tapered to the same current, the cell is
// in the same state, so the true charge between them is zero up to the side reaction's share
// (at a full-charge anchor the loss shows in the flat anode, not in the counted charge: measured
// on the paper cell 0.001-0.09 mA against a 10 mA offset). The counted charge over the span
// divided by its duration is the offset. It needs only the measured voltage and current.
//
// Conditions, in the style of an aid source:
//   should_anchor   the first tick of a CV phase (model voltage-driven) whose |I| has fallen to
//                   Config::anchor_current_a: an end point of its kind (CV charge or discharge);
//   should_fuse     an earlier anchor of the same kind exists, at the same voltage
//                   (Config::voltage_match_v), the span is within [min_span_s, max_span_s] and
//                   no power cycle lies between; the span's mean current is within
//                   Config::limit_a (a larger one is not a sensor offset: the file or the cell
//                   is not what the model thinks, and nothing is corrected);
//   continue        the offset is the running mean of the fused spans (the last
//                   Config::average_over weighted equally), subtracted from every accepted
//                   sample's current from the next tick on when it is outside the dead band
//                   (a move of the offset in use by more than the dead band restarts the film
//                   path from its prior: BmsCore::follow_offset);
//   stop            a power cycle or a gap over Config::max_gap_s drops the open spans (the
//                   offset stays): a record sampled every second or slower never fuses one.
// The counted charge is kept in double on every target: a float sum over a cycle's 40 000 ticks
// of +-2.5 A loses about a milliampere-hour, the size of what is measured.
// Header-only C++17: no heap, no exceptions, no RTTI.
#include <cmath>
#include <cstdint>

namespace bms::fw {

template <typename Scalar>
class CurrentOffset {
 public:
  struct Config {
    bool enabled = false;
    Scalar anchor_current_a = Scalar(0.25);   // |I| at which a CV phase is an end point
    Scalar voltage_match_v = Scalar(0.005);   // two anchors of one kind are the same state
    Scalar min_span_s = Scalar(1800);         // shorter spans: the trigger's noise dominates
    Scalar max_span_s = Scalar(172800);       // longer: the offset may have drifted
    Scalar limit_a = Scalar(0.05);            // the largest offset a front end's sensor has
    // A smaller offset is not corrected: a span's mean carries the side reaction's share and the
    // trigger's noise, up to 0.09 mA on the paper cell with no offset (3x that).
    Scalar deadband_a = Scalar(0.00025);
    std::uint32_t average_over = 4u;
    Scalar dt_s = Scalar(0.2);
    // A longer gap between two samples drops the open spans: over it the current is interpolated,
    // which misses up to I x gap at a step of the current (2.5 A s at 2.5 A and a 1 s record, four
    // steps a cycle: 1.3 mA over 2 h; 16 A s at 0.55 A and a cycler's 30 s), the size of what is
    // measured. Lost frames (one or two ticks) are kept.
    Scalar max_gap_s = Scalar(0.5);
  };

  // Trivially copyable, for the NVM image. Index 0: CV charge, 1: CV discharge.
  struct State {
    double charge_as[2];          // counted since the anchor [A s]
    double span_s[2];             // time since the anchor
    Scalar anchor_voltage_v[2];
    Scalar offset_a;
    Scalar last_current_a;        // the last accepted sample's measured current
    std::uint32_t fused;          // spans fused so far
    std::uint32_t flags;          // bit k: anchor k set; bit 2: anchored in this CV phase
  };

  explicit CurrentOffset(const Config& config) : c_(config) {}

  // The current the model and the estimator see.
  Scalar corrected(Scalar measured_a) const { return measured_a - offset_a(); }
  // The offset subtracted (0 within the dead band or when off).
  Scalar offset_a() const { return c_.enabled && std::fabs(offset_a_) > c_.deadband_a ? offset_a_ : Scalar(0); }
  Scalar measured_offset_a() const { return offset_a_; }
  std::uint32_t fused() const { return fused_; }
  const Config& config() const { return c_; }

  // Step 2: counts the measured current over this tick and the `missed` ticks before it (on the
  // current interpolated between the two samples, as the catch-up steps the model).
  void count(Scalar measured_a, std::uint32_t missed, bool first_sample, bool power_cycle) {
    if (!c_.enabled) return;
    if (power_cycle || static_cast<Scalar>(missed) * c_.dt_s > c_.max_gap_s) drop_spans();
    const double dt = static_cast<double>(c_.dt_s);
    double q = static_cast<double>(measured_a) * dt;
    if (!first_sample && !power_cycle && missed > 0u)
      q += 0.5 * (static_cast<double>(last_current_a_) + static_cast<double>(measured_a)) * dt * missed;
    const double span = dt * (static_cast<double>(missed) + 1.0);
    for (int k = 0; k < 2; ++k) {
      charge_as_[k] += q;
      span_s_[k] += span;
    }
    last_current_a_ = measured_a;
  }

  bool should_anchor(bool voltage_driven, Scalar measured_a) const {
    return c_.enabled && voltage_driven && !anchored_in_phase_ && std::fabs(measured_a) <= c_.anchor_current_a;
  }

  // Step 7 (the model's drive of this tick known); true when a span was fused in this tick.
  bool follow_phase(bool voltage_driven, bool charging, Scalar voltage_v, Scalar measured_a) {
    if (!voltage_driven) {
      anchored_in_phase_ = false;
      return false;
    }
    if (!should_anchor(voltage_driven, measured_a)) return false;
    anchored_in_phase_ = true;
    const int k = charging ? 0 : 1;
    const bool fused = should_fuse(k, voltage_v) && fuse(charge_as_[k] / span_s_[k]);
    anchor_set_[k] = true;
    anchor_voltage_v_[k] = voltage_v;
    charge_as_[k] = 0.0;
    span_s_[k] = 0.0;
    return fused;
  }

  State save() const {
    State s{};
    for (int k = 0; k < 2; ++k) {
      s.charge_as[k] = charge_as_[k];
      s.span_s[k] = span_s_[k];
      s.anchor_voltage_v[k] = anchor_voltage_v_[k];
    }
    s.offset_a = offset_a_;
    s.last_current_a = last_current_a_;
    s.fused = fused_;
    s.flags = (anchor_set_[0] ? 1u : 0u) | (anchor_set_[1] ? 2u : 0u) | (anchored_in_phase_ ? 4u : 0u);
    return s;
  }

  // The offset within +-limit_a, spans non-negative, every value finite.
  bool restore(const State& s) {
    bool ok = (s.flags & ~7u) == 0u && std::isfinite(s.offset_a) && std::fabs(s.offset_a) <= c_.limit_a &&
              std::isfinite(s.last_current_a);
    for (int k = 0; k < 2; ++k)
      ok = ok && std::isfinite(s.charge_as[k]) && std::isfinite(s.span_s[k]) && s.span_s[k] >= 0.0 &&
           std::isfinite(s.anchor_voltage_v[k]);
    if (!ok) return false;
    for (int k = 0; k < 2; ++k) {
      charge_as_[k] = s.charge_as[k];
      span_s_[k] = s.span_s[k];
      anchor_voltage_v_[k] = s.anchor_voltage_v[k];
      anchor_set_[k] = (s.flags & (1u << k)) != 0u;
    }
    offset_a_ = s.offset_a;
    last_current_a_ = s.last_current_a;
    fused_ = s.fused;
    anchored_in_phase_ = (s.flags & 4u) != 0u;
    return true;
  }

 private:
  bool should_fuse(int k, Scalar voltage_v) const {
    const double span = span_s_[k];
    return anchor_set_[k] && std::fabs(voltage_v - anchor_voltage_v_[k]) <= c_.voltage_match_v &&
           span >= static_cast<double>(c_.min_span_s) && span <= static_cast<double>(c_.max_span_s);
  }

  bool fuse(double mean_a) {
    if (!(std::fabs(mean_a) <= static_cast<double>(c_.limit_a))) return false;
    if (fused_ < 0xFFFFFFFFu) ++fused_;
    const std::uint32_t n = fused_ < c_.average_over ? fused_ : c_.average_over;
    offset_a_ = offset_a_ + (static_cast<Scalar>(mean_a) - offset_a_) / static_cast<Scalar>(n == 0u ? 1u : n);
    return true;
  }

  void drop_spans() {
    anchor_set_[0] = anchor_set_[1] = false;
    anchored_in_phase_ = false;
  }

  Config c_;
  double charge_as_[2] = {0.0, 0.0};
  double span_s_[2] = {0.0, 0.0};
  Scalar anchor_voltage_v_[2] = {Scalar(0), Scalar(0)};
  bool anchor_set_[2] = {false, false};
  bool anchored_in_phase_ = false;
  Scalar offset_a_ = Scalar(0);
  Scalar last_current_a_ = Scalar(0);
  std::uint32_t fused_ = 0u;
};

}  // namespace bms::fw
