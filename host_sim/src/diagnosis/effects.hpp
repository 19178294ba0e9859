#pragma once
// The candidate effects of the diagnosis (contract names) and how each is added to the model
// under test: contact resistance, hysteresis and the thermal model are switches of the truth
// model (ModelEffects); a current-sensor offset or gain means the true current differs from
// the measured one, so the model is driven with the corrected current.
#include <string>
#include <string_view>
#include <type_traits>
#include <utility>
#include <vector>

#include "dfn/dfn_model.hpp"

namespace bms::diagnosis {

enum class Effect { none, contact_resistance, hysteresis, current_offset, current_gain, thermal, particle_size };

inline constexpr Effect kAllCandidates[] = {Effect::contact_resistance, Effect::hysteresis, Effect::current_offset,
                                            Effect::current_gain, Effect::thermal};
// particle_size (cathode particle-size spread) is scored only when listed in --candidates: it
// is a hypothesis about the cell's structure, not a sensor or wiring fault, and leaving it out
// of `all` keeps the earlier diagnoses (and their run times) as they were.

const char* effect_name(Effect e);
bool parse_effect(std::string_view name, Effect& out);
const char* parameter_name(Effect e);  // key in summary.json "parameters", with its unit

struct EffectSetting {
  Effect effect = Effect::none;
  double value = 0.0;  // in the contract's unit for the effect
};

// hysteresis_v and thermal_h_w_per_k are being added to ModelEffects by issue 7's truth-model
// work; until they exist the candidates are reported as unavailable instead of breaking the
// build. The detection is at compile time, so nothing changes at run time once they land.
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
    case Effect::none:
    case Effect::current_offset:
    case Effect::current_gain: return true;  // not a model switch
  }
  return false;
}

// Whether this build's truth model can represent the effect.
bool effect_available(Effect e);

// The current that drives the model: the measured one, corrected for a sensor offset
// (reads value A high) or gain (reads (1 + value) times the true current).
std::vector<double> driving_current(const EffectSetting& s, const std::vector<double>& measured_a);

}  // namespace bms::diagnosis
