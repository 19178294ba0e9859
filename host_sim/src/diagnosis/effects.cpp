#include "diagnosis/effects.hpp"

namespace bms::diagnosis {

const char* effect_name(Effect e) {
  switch (e) {
    case Effect::none: return "none";
    case Effect::contact_resistance: return "contact_resistance";
    case Effect::hysteresis: return "hysteresis";
    case Effect::current_offset: return "current_offset";
    case Effect::current_gain: return "current_gain";
    case Effect::thermal: return "thermal";
    case Effect::particle_size: return "particle_size";
  }
  return "none";
}

bool parse_effect(std::string_view name, Effect& out) {
  for (Effect e : {Effect::none, Effect::contact_resistance, Effect::hysteresis, Effect::current_offset,
                   Effect::current_gain, Effect::thermal, Effect::particle_size}) {
    if (name == effect_name(e)) {
      out = e;
      return true;
    }
  }
  return false;
}

const char* parameter_name(Effect e) {
  switch (e) {
    case Effect::none: return "";
    case Effect::contact_resistance: return "contact_resistance_ohm";
    case Effect::hysteresis: return "hysteresis_v";
    case Effect::current_offset: return "current_offset_a";
    case Effect::current_gain: return "current_gain";
    case Effect::thermal: return "thermal_h_w_per_k";
    case Effect::particle_size: return "particle_size_sigma";
  }
  return "";
}

bool effect_available(Effect e) {
  ModelEffects probe;
  return set_model_effect(probe, EffectSetting{e, 0.0});
}

std::vector<double> driving_current(const EffectSetting& s, const std::vector<double>& measured_a) {
  std::vector<double> out = measured_a;
  if (s.effect == Effect::current_offset) {
    for (double& i : out) i -= s.value;
  } else if (s.effect == Effect::current_gain) {
    for (double& i : out) i /= 1.0 + s.value;
  }
  return out;
}

}  // namespace bms::diagnosis
