#pragma once
// The knobs of the diagnosis and how each is added to the model under test. Three kinds:
//  - model switches of the truth DFN (contact resistance, hysteresis, thermal, particle size);
//  - drive corrections: a current-sensor offset or gain means the true current differs from the
//    measured one, so the model is driven with the corrected current; a start-state offset;
//  - parameter re-fits: a factor on one of the cell's own parameters (the `simulate --set` names);
//  - measurement structure applied to the model's voltage after the run, no re-run needed:
//    voltage-sensor offset and gain, an extra RC relaxation branch, a time skew between the
//    voltage and the current samples.
// A candidate is one knob, except `rc_branch` (resistance and time constant together),
// `diffusivity_profile_positive` (the profile's size and its knee) and
// `resistive_reactant_positive` (the resistance, its rise and its knee).
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include "dfn/dfn_model.hpp"

namespace bms::diagnosis {

enum class Effect {
  none,
  contact_resistance,
  hysteresis,
  current_offset,
  current_gain,
  thermal,
  particle_size,
  voltage_offset,
  voltage_gain,
  rc_branch,  // its resistance; the time constant is the knob rc_time_constant
  rc_time_constant,
  time_skew,
  diffusivity_positive,
  diffusivity_negative,
  conductivity,
  electrolyte_diffusivity,
  i0_positive,
  i0_negative,
  initial_soc,
  // The cathode's solid diffusivity as a function of stoichiometry (a knee profile: log10 of the
  // factor at full lithiation; its knee is the knob diffusivity_profile_knee).
  diffusivity_profile_positive,
  diffusivity_profile_knee,
  // The cathode's resistive reactant (ModelEffects): the resistance below the knee (ohm m2),
  // the decades it rises to full lithiation and the knee.
  resistive_reactant_positive,
  resistive_reactant_log10,
  resistive_reactant_knee,
  unexplained,  // an answer, not a knob: a residual remains that no candidate explains
};

enum class KnobKind { model_switch, drive, parameter, post };

// The listed effects first, then the structural ones, then the parameter re-fits.
inline constexpr Effect kAllCandidates[] = {
    Effect::contact_resistance,   Effect::hysteresis,   Effect::current_offset,          Effect::current_gain,
    Effect::thermal,              Effect::voltage_offset, Effect::voltage_gain,          Effect::rc_branch,
    Effect::time_skew,            Effect::diffusivity_positive, Effect::diffusivity_negative, Effect::conductivity,
    Effect::electrolyte_diffusivity, Effect::i0_positive, Effect::i0_negative,            Effect::initial_soc,
    Effect::diffusivity_profile_positive, Effect::resistive_reactant_positive};
// The five listed effects (`--candidates listed`).
inline constexpr Effect kListedCandidates[] = {Effect::contact_resistance, Effect::hysteresis, Effect::current_offset,
                                               Effect::current_gain, Effect::thermal};
// particle_size (cathode particle-size spread) is scored only when listed in --candidates: each
// of its runs carries three particle populations, and it is kept as an off-list effect for the
// honesty tests.

const char* effect_name(Effect e);
bool parse_effect(std::string_view name, Effect& out);
const char* parameter_name(Effect e);  // key in summary.json "parameters", with its unit
KnobKind knob_kind(Effect e);
// The knobs a candidate fits (rc_branch: time constant, then resistance).
std::vector<Effect> knobs_of(Effect candidate);
// What a fitted value means physically, and whether it is plausible (a sentence).
std::string plausibility_note(Effect e, double value);
std::string format_value(Effect e, double value);

struct EffectSetting {
  Effect effect = Effect::none;
  double value = 0.0;  // in the unit of parameter_name(effect)
};
using Hypothesis = std::vector<EffectSetting>;

// The value of a knob in h (fallback when absent).
double knob_value(const Hypothesis& h, Effect e, double fallback = 0.0);

// hysteresis_v and thermal_h_w_per_k are detected at compile time so that a truth model
// without them reports the candidates as unavailable instead of breaking the build.
template <class E, class = void>
struct HasHysteresis : std::false_type {};
template <class E>
struct HasHysteresis<E, std::void_t<decltype(std::declval<E&>().hysteresis_v)>> : std::true_type {};
template <class E, class = void>
struct HasThermal : std::false_type {};
template <class E>
struct HasThermal<E, std::void_t<decltype(std::declval<E&>().thermal_h_w_per_k)>> : std::true_type {};

template <class E>
bool set_model_effect(E& effects, const EffectSetting& s) {
  switch (s.effect) {
    case Effect::contact_resistance: effects.contact_resistance_ohm = s.value; return true;
    case Effect::hysteresis:
      if constexpr (HasHysteresis<E>::value) {
        effects.hysteresis_v = s.value;
        return true;
      } else {
        return false;
      }
    case Effect::thermal:
      if constexpr (HasThermal<E>::value) {
        effects.thermal_h_w_per_k = s.value;
        return true;
      } else {
        return false;
      }
    case Effect::particle_size: effects.particle_size_sigma = s.value; return true;
    case Effect::diffusivity_profile_positive: effects.diffusivity_profile_positive = s.value; return true;
    case Effect::diffusivity_profile_knee: effects.diffusivity_profile_positive_knee = s.value; return true;
    case Effect::resistive_reactant_positive: effects.resistive_reactant_positive_ohm_m2 = s.value; return true;
    case Effect::resistive_reactant_log10: effects.resistive_reactant_positive_log10 = s.value; return true;
    case Effect::resistive_reactant_knee: effects.resistive_reactant_positive_knee = s.value; return true;
    default: return true;  // not a model switch
  }
}

// Whether this build's truth model can represent the effect.
bool effect_available(Effect e);

// The current that drives the model: the measured one, corrected for a sensor offset
// (reads value A high) or gain (reads (1 + value) times the true current).
std::vector<double> driving_current(const EffectSetting& s, const std::vector<double>& measured_a);
std::vector<double> driving_current(const Hypothesis& h, const std::vector<double>& measured_a);

// The `simulate --set` name of a parameter re-fit ("" for the other kinds).
const char* truth_parameter_of(Effect e);

// The measurement structure of h applied to a model voltage (post knobs only): the time
// skew (the voltage sample at t_k belongs to t_k + skew), the RC branch's drop, then the
// voltage sensor's gain and offset.
std::vector<double> apply_post(const Hypothesis& h, const std::vector<double>& t_s,
                               const std::vector<double>& current_a, const std::vector<double>& model_v);

}  // namespace bms::diagnosis
