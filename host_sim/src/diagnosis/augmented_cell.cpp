#include "diagnosis/augmented_cell.hpp"

#include <fmt/format.h>

#include "io/bpx_writer.hpp"

namespace bms::diagnosis {

namespace {

// Where a parameter re-fit's factor goes in BPX.
struct ScaledField {
  Effect effect;
  const char* section;
  const char* key;
};
constexpr ScaledField kScaled[] = {
    {Effect::diffusivity_positive, "Positive electrode", "Diffusivity [m2.s-1]"},
    {Effect::diffusivity_negative, "Negative electrode", "Diffusivity [m2.s-1]"},
    {Effect::conductivity, "Electrolyte", "Conductivity [S.m-1]"},
    {Effect::electrolyte_diffusivity, "Electrolyte", "Diffusivity [m2.s-1]"},
    {Effect::i0_positive, "Positive electrode", "Reaction rate constant [mol.m-2.s-1]"},
    {Effect::i0_negative, "Negative electrode", "Reaction rate constant [mol.m-2.s-1]"},
};

// The User-defined key of a model switch (the reader's, io/bpx_reader.cpp).
const char* user_key(Effect e) {
  switch (e) {
    case Effect::contact_resistance: return "Contact resistance [Ohm]";
    case Effect::hysteresis: return "OCP hysteresis half-gap [V]";
    case Effect::thermal: return "Lumped heat transfer coefficient [W.K-1]";
    case Effect::particle_size: return "Positive particle-size log-normal standard deviation [-]";
    case Effect::diffusivity_profile_positive: return "Positive diffusivity profile log10 factor at full lithiation [-]";
    case Effect::diffusivity_profile_knee: return "Positive diffusivity profile knee stoichiometry [-]";
    case Effect::resistive_reactant_positive: return "Positive resistive reactant resistance [Ohm.m2]";
    case Effect::resistive_reactant_log10: return "Positive resistive reactant log10 rise at full lithiation [-]";
    case Effect::resistive_reactant_knee: return "Positive resistive reactant knee stoichiometry [-]";
    default: return nullptr;
  }
}

}  // namespace

std::string not_a_cell_property(Effect e, double v) {
  switch (e) {
    case Effect::current_offset:
    case Effect::current_gain:
      return fmt::format("{} ({}) is an error of the current sensor, not a property of the cell; simulate it with "
                         "--effect {}={:.6g}, or diagnose without it in --candidates",
                         effect_name(e), format_value(e, v), effect_name(e), v);
    case Effect::voltage_offset:
    case Effect::voltage_gain:
      return fmt::format("{} ({}) is an error of the voltage sensor, not a property of the cell; diagnose without it "
                         "in --candidates",
                         effect_name(e), format_value(e, v));
    case Effect::time_skew:
      return fmt::format("time_skew ({}) is a skew between the logged voltage and current, not a property of the "
                         "cell; diagnose without it in --candidates",
                         format_value(e, v));
    case Effect::rc_branch:
    case Effect::rc_time_constant:
      return fmt::format("rc_branch ({}) has no counterpart in the truth model a cell file feeds; diagnose without it "
                         "in --candidates",
                         format_value(e, v));
    case Effect::initial_soc:
      return fmt::format("initial_soc ({}) is the record's start state, not a property of the cell; diagnose without "
                         "it in --candidates (simulate starts from the cell's default state or --ic-error-pct)",
                         format_value(e, v));
    default: return "";
  }
}

AugmentedCell augment_cell(const nlohmann::json& input_bpx, const CellParameters& input, const Hypothesis& h) {
  AugmentedCell out;
  out.bpx = input_bpx;
  for (const EffectSetting& s : h) {
    if (std::string why = not_a_cell_property(s.effect, s.value); !why.empty()) {
      out.refused = why;
      return out;
    }
    std::string where;
    double written = s.value;
    if (const char* key = user_key(s.effect)) {
      if (s.effect == Effect::contact_resistance) written += input.effects.contact_resistance_ohm;
      bpx_field(out.bpx, "User-defined", key) = written;
      where = fmt::format("User-defined.{} = {:.6g}", key, written);
    } else {
      const ScaledField* f = nullptr;
      for (const auto& c : kScaled)
        if (c.effect == s.effect) f = &c;
      if (f == nullptr) {
        out.refused = fmt::format("{}: no place in a cell file for this knob", effect_name(s.effect));
        return out;
      }
      const std::string name = std::string(f->section) + "." + f->key;
      if (!out.bpx.at("Parameterisation").contains(f->section) ||
          !out.bpx["Parameterisation"][f->section].contains(f->key)) {
        out.refused = fmt::format("{}: the input cell has no field '{}' to scale", effect_name(s.effect), name);
        return out;
      }
      scale_bpx_value(bpx_field(out.bpx, f->section, f->key), s.value, name);
      where = fmt::format("{} x {:.6g}", name, s.value);
    }
    out.added.push_back(fmt::format("{} {}: {}", effect_name(s.effect), format_value(s.effect, s.value), where));
    out.added_json.push_back({{"effect", effect_name(s.effect)},
                              {"value", s.value},
                              {"unit_name", parameter_name(s.effect)},
                              {"written", where},
                              {"line", out.added.back()}});
  }
  return out;
}

}  // namespace bms::diagnosis
