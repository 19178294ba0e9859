#include "diagnosis/effects.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace bms::diagnosis {

namespace {

struct KnobInfo {
  Effect effect;
  const char* name;
  const char* parameter;
  KnobKind kind;
  const char* truth_name;
};

constexpr KnobInfo kKnobs[] = {
    {Effect::none, "none", "", KnobKind::model_switch, ""},
    {Effect::contact_resistance, "contact_resistance", "contact_resistance_ohm", KnobKind::model_switch, ""},
    {Effect::hysteresis, "hysteresis", "hysteresis_v", KnobKind::model_switch, ""},
    {Effect::current_offset, "current_offset", "current_offset_a", KnobKind::drive, ""},
    {Effect::current_gain, "current_gain", "current_gain", KnobKind::drive, ""},
    {Effect::thermal, "thermal", "thermal_h_w_per_k", KnobKind::model_switch, ""},
    {Effect::particle_size, "particle_size", "particle_size_sigma", KnobKind::model_switch, ""},
    {Effect::voltage_offset, "voltage_offset", "voltage_offset_v", KnobKind::post, ""},
    {Effect::voltage_gain, "voltage_gain", "voltage_gain", KnobKind::post, ""},
    {Effect::rc_branch, "rc_branch", "rc_resistance_ohm", KnobKind::post, ""},
    {Effect::rc_time_constant, "rc_time_constant", "rc_time_constant_s", KnobKind::post, ""},
    {Effect::time_skew, "time_skew", "time_skew_s", KnobKind::post, ""},
    {Effect::diffusivity_positive, "diffusivity_positive", "diffusivity_scale_positive", KnobKind::parameter,
     "diffusivity_scale_positive"},
    {Effect::diffusivity_negative, "diffusivity_negative", "diffusivity_scale_negative", KnobKind::parameter,
     "diffusivity_scale_negative"},
    {Effect::conductivity, "conductivity", "conductivity_scale", KnobKind::parameter, "conductivity_scale"},
    {Effect::electrolyte_diffusivity, "electrolyte_diffusivity", "electrolyte_diffusivity_scale",
     KnobKind::parameter, "electrolyte_diffusivity_scale"},
    {Effect::i0_positive, "i0_positive", "i0_scale_positive", KnobKind::parameter, "i0_scale_positive"},
    {Effect::i0_negative, "i0_negative", "i0_scale_negative", KnobKind::parameter, "i0_scale_negative"},
    {Effect::initial_soc, "initial_soc", "initial_soc_offset", KnobKind::drive, ""},
    {Effect::diffusivity_profile_positive, "diffusivity_profile_positive", "diffusivity_profile_positive_log10",
     KnobKind::model_switch, ""},
    {Effect::diffusivity_profile_knee, "diffusivity_profile_knee", "diffusivity_profile_positive_knee",
     KnobKind::model_switch, ""},
    {Effect::resistive_reactant_positive, "resistive_reactant_positive", "resistive_reactant_positive_ohm_m2",
     KnobKind::model_switch, ""},
    {Effect::resistive_reactant_log10, "resistive_reactant_log10", "resistive_reactant_positive_log10",
     KnobKind::model_switch, ""},
    {Effect::resistive_reactant_knee, "resistive_reactant_knee", "resistive_reactant_positive_knee",
     KnobKind::model_switch, ""},
    {Effect::unexplained, "unexplained", "", KnobKind::model_switch, ""},
};

const KnobInfo& info(Effect e) {
  for (const auto& k : kKnobs)
    if (k.effect == e) return k;
  return kKnobs[0];
}

}  // namespace

const char* effect_name(Effect e) { return info(e).name; }
const char* parameter_name(Effect e) { return info(e).parameter; }
KnobKind knob_kind(Effect e) { return info(e).kind; }
const char* truth_parameter_of(Effect e) { return info(e).truth_name; }

bool parse_effect(std::string_view name, Effect& out) {
  for (const auto& k : kKnobs) {
    if (name == k.name && k.effect != Effect::rc_time_constant && k.effect != Effect::diffusivity_profile_knee &&
        k.effect != Effect::resistive_reactant_log10 && k.effect != Effect::resistive_reactant_knee &&
        k.effect != Effect::unexplained) {
      out = k.effect;
      return true;
    }
  }
  return false;
}

std::vector<Effect> knobs_of(Effect candidate) {
  if (candidate == Effect::rc_branch) return {Effect::rc_time_constant, Effect::rc_branch};
  if (candidate == Effect::diffusivity_profile_positive)
    return {Effect::diffusivity_profile_positive, Effect::diffusivity_profile_knee};
  if (candidate == Effect::resistive_reactant_positive)
    return {Effect::resistive_reactant_positive, Effect::resistive_reactant_log10, Effect::resistive_reactant_knee};
  return {candidate};
}

double knob_value(const Hypothesis& h, Effect e, double fallback) {
  for (const auto& s : h)
    if (s.effect == e) return s.value;
  return fallback;
}

std::string format_value(Effect e, double v) {
  switch (e) {
    case Effect::contact_resistance: return fmt::format("{:.4g} mohm", 1e3 * v);
    case Effect::hysteresis: return fmt::format("{:.4g} mV", 1e3 * v);
    case Effect::current_offset: return fmt::format("{:.4g} mA", 1e3 * v);
    case Effect::current_gain: return fmt::format("{:.4g} %", 100.0 * v);
    case Effect::thermal: return fmt::format("{:.4g} W/K", v);
    case Effect::particle_size: return fmt::format("sigma {:.4g}", v);
    case Effect::voltage_offset: return fmt::format("{:.4g} mV", 1e3 * v);
    case Effect::voltage_gain: return fmt::format("{:.4g} %", 100.0 * v);
    case Effect::rc_branch: return fmt::format("{:.4g} mohm", 1e3 * v);
    case Effect::rc_time_constant: return fmt::format("{:.4g} s", v);
    case Effect::time_skew: return fmt::format("{:.4g} s", v);
    case Effect::initial_soc: return fmt::format("{:+.4g} % SOC", 100.0 * v);
    case Effect::diffusivity_profile_positive: return fmt::format("D x {:.4g} at full lithiation", std::pow(10.0, v));
    case Effect::diffusivity_profile_knee: return fmt::format("knee at x = {:.4g}", v);
    case Effect::resistive_reactant_positive: return fmt::format("{:.4g} ohm m2 below the knee", v);
    case Effect::resistive_reactant_log10: return fmt::format("x {:.4g} at full lithiation", std::pow(10.0, v));
    case Effect::resistive_reactant_knee: return fmt::format("knee at x = {:.4g}", v);
    case Effect::none: return "-";
    default: return fmt::format("x {:.4g}", v);
  }
}

// Typical sizes: models.md section 5 for the listed effects; a factor on a literature
// parameter within 0.3..3 is inside the usual spread of published DFN sets.
std::string plausibility_note(Effect e, double v) {
  switch (e) {
    case Effect::contact_resistance:
      return v <= 0.01 ? "plausible: a tab or fixture contact of a few mohm" : "large for a contact: check the fixture";
    case Effect::hysteresis: return v <= 0.03 ? "plausible for LFP (10-20 mV half-gap typical)" : "larger than LFP's";
    case Effect::current_offset:
    case Effect::current_gain: return "a sensor error: check the cycler's calibration";
    case Effect::thermal: return "lumped heat loss; an 18650 in free air is 0.05-0.2 W/K";
    case Effect::voltage_offset:
    case Effect::voltage_gain: return "a voltage-sensor error: check the cycler's calibration";
    case Effect::rc_branch:
    case Effect::rc_time_constant: return "a relaxation the DFN does not carry (a lumped, non-physical correction)";
    case Effect::time_skew: return std::abs(v) <= 1.0 ? "within one sample" : "more than one sample: a logging lag";
    case Effect::initial_soc: return "the start state differs from the first-rest-voltage estimate";
    case Effect::diffusivity_profile_positive:
    case Effect::diffusivity_profile_knee:
      return "a cathode diffusivity that changes with lithiation (LFP's varies by decades across x)";
    case Effect::resistive_reactant_positive:
    case Effect::resistive_reactant_log10:
    case Effect::resistive_reactant_knee:
      return "a reaction resistance that grows as the cathode particles fill (LiFePO4 conducts worse than FePO4)";
    default: break;
  }
  if (truth_parameter_of(e)[0] != '\0')
    return v >= 0.3 && v <= 3.0 ? "within the usual spread of published DFN parameters (x0.3..x3)"
                                : "outside x0.3..x3 of the parameter set: a structural gap more likely than a value";
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

std::vector<double> driving_current(const Hypothesis& h, const std::vector<double>& measured_a) {
  const double offset = knob_value(h, Effect::current_offset), gain = knob_value(h, Effect::current_gain);
  std::vector<double> out(measured_a.size());
  for (std::size_t k = 0; k < out.size(); ++k) out[k] = (measured_a[k] - offset) / (1.0 + gain);
  return out;
}

std::vector<double> apply_post(const Hypothesis& h, const std::vector<double>& t_s,
                               const std::vector<double>& current_a, const std::vector<double>& model_v) {
  std::vector<double> v = model_v;
  const std::size_t n = v.size();
  const double skew = knob_value(h, Effect::time_skew);
  if (skew != 0.0 && n > 1) {
    std::size_t j = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const double t = t_s[k] + skew;
      while (j + 2 < n && t_s[j + 1] < t) ++j;
      const double w = std::clamp((t - t_s[j]) / (t_s[j + 1] - t_s[j]), 0.0, 1.0);
      v[k] = (1.0 - w) * model_v[j] + w * model_v[j + 1];
      if (!std::isfinite(v[k])) v[k] = model_v[k];
    }
  }
  const double r_ohm = knob_value(h, Effect::rc_branch);
  if (r_ohm != 0.0) {
    const double tau_s = knob_value(h, Effect::rc_time_constant, 100.0);
    double x_a = 0.0;  // the branch's current (positive = discharge)
    for (std::size_t k = 1; k < n; ++k) {
      const double a = std::exp(-(t_s[k] - t_s[k - 1]) / tau_s);
      x_a = a * x_a + (1.0 - a) * 0.5 * (current_a[k] + current_a[k - 1]);
      v[k] -= r_ohm * x_a;
    }
  }
  const double gain = knob_value(h, Effect::voltage_gain), offset = knob_value(h, Effect::voltage_offset);
  if (gain != 0.0 || offset != 0.0)
    for (double& x : v) x = (1.0 + gain) * x + offset;
  return v;
}

}  // namespace bms::diagnosis
