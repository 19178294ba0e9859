#pragma once
// Cell and sensor effects the reduced model lacks, as a wrapper around any main-system model
// with the ReducedCell interface: contact resistance, one-state OCV
// hysteresis, current-sensor offset and gain. The diagnosis (bmssim diagnose) names the effect
// and estimates its parameter from the data; the firmware then runs
//   BmsCore<Scalar, EffectsModel<ReducedCell<Scalar>, kEffectContactResistance | ...>>
// unchanged. Which effects exist is a compile-time choice (a disabled effect costs no
// arithmetic and no Newton pass); their sizes are run-time parameters.
//
// Conventions are the truth model's (host_sim/src/dfn/dfn_model.cpp, ModelEffects), so a
// parameter diagnosed against the truth means the same here:
//   cell current     I = (I_meas - offset) / (1 + gain)        (positive = discharge)
//   terminal voltage V = V_inner(I) - R_c I + h
//   hysteresis       dh/dt = -(kappa / (3600 Q_nom)) (H I + |I| h),  h(0) = branch * H
// The hysteresis ODE is integrated exactly over a tick at the tick's constant current, so it
// does not depend on the tick length; V uses h at the end of the tick (the inner model is
// backward Euler: its voltage is the end-of-tick voltage too).
//
// Voltage-driven ticks (CV): the inner model must reach V_inner = V_meas + R_c I - h(I), a
// target that depends on the current it is solving for. The inner model is stepped to a
// target, restored, and re-stepped to a secant update of the target, at most
// kMaxVoltagePasses times (a fixed worst case). The target moves by R_c / R_cell per ampere
// of mismatch (a few % for milliohms), so two or three passes reach the tolerance.
//
// Firmware rules: no heap, no exceptions, no RTTI, no globals; Scalar = float works.
#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>
#include <utility>

#include "bms/fw/model/reduced_cell.hpp"

namespace bms::fw {

enum EffectFlag : unsigned {
  kEffectContactResistance = 1u << 0,
  kEffectHysteresis = 1u << 1,
  kEffectCurrentOffset = 1u << 2,
  kEffectCurrentGain = 1u << 3,
};
inline constexpr unsigned kAllCellEffects =
    kEffectContactResistance | kEffectHysteresis | kEffectCurrentOffset | kEffectCurrentGain;

// Run-time sizes. Parameters of effects that are compiled out are ignored.
template <typename Scalar>
struct EffectParameters {
  Scalar contact_resistance_ohm = Scalar(0);
  Scalar hysteresis_v = Scalar(0);               // H: half the gap between the OCV branches
  Scalar hysteresis_rate_per_soc = Scalar(50);   // kappa: the truth model's default
  Scalar hysteresis_initial_branch = Scalar(1);  // h(0) / H: +1 = just charged (the truth's default)
  Scalar nominal_capacity_ah = Scalar(0);        // Q_nom, scales the hysteresis rate (needed when H > 0)
  Scalar current_offset_a = Scalar(0);           // sensor reads I (1 + gain) + offset
  Scalar current_gain = Scalar(0);
};

// Checks a parameter set; returns the first offending field's index (1-based, in declaration
// order) or 0 when every field is usable. The firmware has no exceptions; the host turns the
// index into a message naming the field.
template <typename Scalar>
int invalid_effect_parameter(const EffectParameters<Scalar>& p) {
  if (!(std::isfinite(p.contact_resistance_ohm) && p.contact_resistance_ohm >= Scalar(0))) return 1;
  if (!(std::isfinite(p.hysteresis_v) && p.hysteresis_v >= Scalar(0) && p.hysteresis_v <= Scalar(0.5))) return 2;
  if (!(std::isfinite(p.hysteresis_rate_per_soc) && p.hysteresis_rate_per_soc > Scalar(0))) return 3;
  if (!(std::fabs(p.hysteresis_initial_branch) <= Scalar(1))) return 4;
  // Q_nom only matters (and must be known) when there is a hysteresis to scale.
  if (p.hysteresis_v > Scalar(0) && !(std::isfinite(p.nominal_capacity_ah) && p.nominal_capacity_ah > Scalar(0)))
    return 5;
  if (!std::isfinite(p.current_offset_a)) return 6;
  if (!(std::fabs(p.current_gain) < Scalar(0.5))) return 7;
  return 0;
}

template <typename Inner, unsigned Effects>
class EffectsModel {
 public:
  using Scalar = std::decay_t<decltype(std::declval<const Inner&>().li_loss_mol())>;
  using InnerState = std::decay_t<decltype(std::declval<const Inner&>().state())>;
  using Parameters = EffectParameters<Scalar>;
  static_assert((Effects & ~kAllCellEffects) == 0u, "unknown effect flag");
  static constexpr bool kContact = (Effects & kEffectContactResistance) != 0u;
  static constexpr bool kHysteresis = (Effects & kEffectHysteresis) != 0u;
  static constexpr bool kOffset = (Effects & kEffectCurrentOffset) != 0u;
  static constexpr bool kGain = (Effects & kEffectCurrentGain) != 0u;
  // Only these two make the CV target depend on the current being solved for.
  static constexpr bool kVoltageCoupled = kContact || kHysteresis;
  static constexpr int kMaxVoltagePasses = 4;

  struct State {
    InnerState inner;
    Scalar hysteresis_v;  // h, the hysteresis voltage now
    Scalar current_a;     // last cell current (start of the CV target search)
  };

  // The inner model is the caller's (initialised by it, as BmsCore expects of its model).
  // Parameters that invalid_effect_parameter rejects leave every effect at zero.
  EffectsModel(Inner& inner, const Parameters& p) : inner_(inner) {
    set_parameters(p);
    reset_hysteresis();
  }

  // Returns false and keeps the previous parameters when p is not usable.
  bool set_parameters(const Parameters& p) {
    if (invalid_effect_parameter(p) != 0) return false;
    p_ = p;
    rate_per_c_ = p.hysteresis_v > Scalar(0) ? p.hysteresis_rate_per_soc / (Scalar(3600) * p.nominal_capacity_ah)
                                             : Scalar(0);
    return true;
  }
  const Parameters& parameters() const { return p_; }

  // The hysteresis state at its initial branch (a fresh cell or an unknown history).
  void reset_hysteresis() { h_v_ = kHysteresis ? p_.hysteresis_initial_branch * p_.hysteresis_v : Scalar(0); }

  ModelTickResult<Scalar> step_current(Scalar current_meas_a, Scalar r_film_ohm_m2, Scalar dt_s) {
    const Scalar current = cell_current(current_meas_a);
    ModelTickResult<Scalar> r = inner_.step_current(current, r_film_ohm_m2, dt_s);
    if (!r.valid) return r;
    h_v_ = hysteresis_after(current, dt_s);
    current_a_ = current;
    r.voltage_v = terminal_voltage(r.voltage_v, current, h_v_);
    r.current_a = sensor_current(current);
    return r;
  }

  ModelTickResult<Scalar> step_voltage(Scalar voltage_v, Scalar r_film_ohm_m2, Scalar dt_s) {
    ModelTickResult<Scalar> r{};
    Scalar h_next = h_v_;
    if constexpr (!kVoltageCoupled) {
      r = inner_.step_voltage(voltage_v, r_film_ohm_m2, dt_s);
    } else {
      const InnerState start = inner_.state();
      // mismatch(target) = target - (V + R_c I(target) - h(I(target))): zero when the
      // terminal voltage with the effects equals V.
      Scalar t0 = inner_target(voltage_v, current_a_, dt_s, h_next);
      r = inner_.step_voltage(t0, r_film_ohm_m2, dt_s);
      Scalar m0 = r.valid ? t0 - inner_target(voltage_v, r.current_a, dt_s, h_next) : Scalar(0);
      Scalar t_prev = t0, m_prev = m0;
      Scalar t = t0 - m0;  // first correction: a plain fixed-point step
      bool converged = r.valid && std::fabs(m0) <= tolerance_v(voltage_v);
      std::uint8_t iterations = r.newton_iterations;
      for (int pass = 1; r.valid && !converged && pass < kMaxVoltagePasses; ++pass) {
        if (!inner_.restore(start)) break;  // cannot fail: the image came from the model
        r = inner_.step_voltage(t, r_film_ohm_m2, dt_s);
        iterations = add_saturated(iterations, r.newton_iterations);
        if (!r.valid) break;
        const Scalar m = t - inner_target(voltage_v, r.current_a, dt_s, h_next);
        converged = std::fabs(m) <= tolerance_v(voltage_v);
        const Scalar dm = m - m_prev;
        // Secant on the target; the mismatch's slope is 1 + R_c / R_cell, about 1.
        const Scalar t_next = dm != Scalar(0) ? t - m * (t - t_prev) / dm : t - m;
        t_prev = t;
        m_prev = m;
        t = t_next;
      }
      if (!r.valid) {
        inner_.restore(start);  // the inner model left its state alone; keep it that way
        return r;
      }
      r.converged = r.converged && converged;
      r.newton_iterations = iterations;
    }
    if (!r.valid) return r;
    const Scalar current = r.current_a;
    h_v_ = kVoltageCoupled ? h_next : hysteresis_after(current, dt_s);
    current_a_ = current;
    r.voltage_v = terminal_voltage(r.voltage_v, current, h_v_);
    r.current_a = sensor_current(current);
    return r;
  }

  // The inner model's observer at the voltage and current it would see: the measured voltage
  // less the effects' share, the measured current corrected for the sensor.
  bool resync(Scalar voltage_v, Scalar current_meas_a, Scalar r_film_ohm_m2, Scalar dt_s, Scalar inventory_mol) {
    const Scalar current = cell_current(current_meas_a);
    Scalar inner_v = voltage_v;
    if constexpr (kContact) inner_v += p_.contact_resistance_ohm * current;
    if constexpr (kHysteresis) inner_v -= h_v_;
    return inner_.resync(inner_v, current, r_film_ohm_m2, dt_s, inventory_mol);
  }

  // The inner model's inventory probe seen through the same effects as this tick's voltage
  // (they cancel in the difference BmsCore takes).
  Scalar inventory_probe_voltage(Scalar current_meas_a, Scalar r_film_ohm_m2, Scalar dt_s, Scalar d_inventory_mol) const {
    const Scalar current = cell_current(current_meas_a);
    return terminal_voltage(inner_.inventory_probe_voltage(current, r_film_ohm_m2, dt_s, d_inventory_mol), current,
                            hysteresis_after(current, dt_s));
  }

  // The inner model's temperature probe through the same effects (none of them depends on the
  // temperature, so they cancel in the difference the film path takes); only where the inner
  // model gives one, so the film sd keeps its temperature-sensor term with effects.
  template <typename I = Inner>
  auto temperature_probe_voltage(Scalar current_meas_a, Scalar r_film_ohm_m2, Scalar dt_s, Scalar d_temperature_k) const
      -> decltype(std::declval<const I&>().temperature_probe_voltage(current_meas_a, r_film_ohm_m2, dt_s, d_temperature_k)) {
    const Scalar current = cell_current(current_meas_a);
    return terminal_voltage(inner_.temperature_probe_voltage(current, r_film_ohm_m2, dt_s, d_temperature_k), current,
                            hysteresis_after(current, dt_s));
  }

  // The inner model's voltage 1-sigma for a stated spread, at the inner model's own current and
  // voltage of the committed tick (the effects are not part of the spread).
  template <typename I = Inner>
  auto spread_voltage_sd_v(Scalar current_meas_a, Scalar voltage_v, const StatedSpread<Scalar>& s) const
      -> decltype(std::declval<const I&>().spread_voltage_sd_v(current_meas_a, voltage_v, s)) {
    const Scalar current = cell_current(current_meas_a);
    Scalar inner_v = voltage_v;
    if constexpr (kContact) inner_v += p_.contact_resistance_ohm * current;
    if constexpr (kHysteresis) inner_v -= h_v_;
    return inner_.spread_voltage_sd_v(current, inner_v, s);
  }

  // The measured cell temperature, passed to the inner model when it takes one.
  bool set_temperature_k(Scalar t_k) {
    if constexpr (kTakesTemperature<Inner, Scalar>) {
      return inner_.set_temperature_k(t_k);
    } else {
      (void)t_k;
      return false;
    }
  }
  // The inner model's open-circuit capacity of an inventory, where it gives one.
  template <typename S = Scalar, typename I = Inner>
  static auto open_circuit_capacity_ah(S inventory_mol) -> decltype(I::open_circuit_capacity_ah(inventory_mol)) {
    return I::open_circuit_capacity_ah(inventory_mol);
  }
  // The inner model's anode lithium, where it gives it.
  template <typename I = Inner>
  auto anode_lithium_mol() const -> decltype(std::declval<const I&>().anode_lithium_mol()) {
    return inner_.anode_lithium_mol();
  }
  template <typename I = Inner>
  auto solid_inventory_mol() const -> decltype(std::declval<const I&>().solid_inventory_mol()) {
    return inner_.solid_inventory_mol();
  }
  Scalar li_loss_ah() const { return inner_.li_loss_ah(); }
  Scalar li_loss_mol() const { return inner_.li_loss_mol(); }
  // The inner model's mean anode stoichiometry, where it gives one (ModelBiasTable's abscissa).
  template <typename I = Inner>
  auto mean_stoich_neg() const -> decltype(std::declval<const I&>().mean_stoich_neg()) {
    return inner_.mean_stoich_neg();
  }
  Scalar hysteresis_v() const { return h_v_; }
  Inner& inner() { return inner_; }
  const Inner& inner() const { return inner_; }

  State state() const { return State{inner_.state(), h_v_, current_a_}; }

  // All or nothing, like the inner model's restore.
  bool restore(const State& s) {
    const Scalar h_bound = p_.hysteresis_v * Scalar(1.0001);
    if (!std::isfinite(s.current_a) || !std::isfinite(s.hysteresis_v)) return false;
    if (kHysteresis ? std::fabs(s.hysteresis_v) > h_bound : s.hysteresis_v != Scalar(0)) return false;
    if (!inner_.restore(s.inner)) return false;
    h_v_ = s.hysteresis_v;
    current_a_ = s.current_a;
    return true;
  }

 private:
  Scalar cell_current(Scalar current_meas_a) const {
    Scalar i = current_meas_a;
    if constexpr (kOffset) i -= p_.current_offset_a;
    if constexpr (kGain) i /= Scalar(1) + p_.current_gain;
    return i;
  }
  Scalar sensor_current(Scalar current_a) const {
    Scalar i = current_a;
    if constexpr (kGain) i *= Scalar(1) + p_.current_gain;
    if constexpr (kOffset) i += p_.current_offset_a;
    return i;
  }
  Scalar terminal_voltage(Scalar inner_v, Scalar current_a, Scalar h_v) const {
    Scalar v = inner_v;
    if constexpr (kContact) v -= p_.contact_resistance_ohm * current_a;
    if constexpr (kHysteresis) v += h_v;
    return v;
  }
  // Exact solution of the hysteresis ODE over dt at constant current: h relaxes towards
  // -H sign(I) with the charge moved, so nothing changes at rest.
  Scalar hysteresis_after(Scalar current_a, Scalar dt_s) const {
    if constexpr (!kHysteresis) {
      return Scalar(0);
    } else {
      const Scalar abs_i = std::fabs(current_a);
      const Scalar h_inf = current_a > Scalar(0) ? -p_.hysteresis_v : (current_a < Scalar(0) ? p_.hysteresis_v : Scalar(0));
      if (abs_i == Scalar(0)) return h_v_;
      return h_inf + (h_v_ - h_inf) * std::exp(-rate_per_c_ * abs_i * dt_s);
    }
  }
  // Inner-model voltage that gives terminal voltage v at cell current i; h_out receives h(i).
  Scalar inner_target(Scalar v, Scalar current_a, Scalar dt_s, Scalar& h_out) const {
    h_out = hysteresis_after(current_a, dt_s);
    Scalar t = v;
    if constexpr (kContact) t += p_.contact_resistance_ohm * current_a;
    if constexpr (kHysteresis) t -= h_out;
    return t;
  }
  static Scalar tolerance_v(Scalar v) {
    // The inner Newton's own tolerance (1e-9 V) in double; a few ulps of V in float.
    const Scalar ulps = Scalar(8) * std::numeric_limits<Scalar>::epsilon() * std::fabs(v);
    return ulps > Scalar(1e-9) ? ulps : Scalar(1e-9);
  }
  static std::uint8_t add_saturated(std::uint8_t a, std::uint8_t b) {
    const unsigned s = static_cast<unsigned>(a) + b;
    return static_cast<std::uint8_t>(s > 255u ? 255u : s);
  }

  Inner& inner_;
  Parameters p_{};
  Scalar rate_per_c_ = Scalar(0);
  Scalar h_v_ = Scalar(0);
  Scalar current_a_ = Scalar(0);
};

}  // namespace bms::fw
