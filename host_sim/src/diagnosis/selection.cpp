#include "diagnosis/selection.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace bms::diagnosis {

namespace {
// At one constant current: a shift by a constant (contact resistance, hysteresis, a voltage
// offset) or a scaling of the current (sensor offset and gain).
int twin_class(Effect e) {
  switch (e) {
    case Effect::contact_resistance:
    case Effect::hysteresis:
    case Effect::voltage_offset: return 1;
    case Effect::current_offset:
    case Effect::current_gain: return 2;
    default: return 0;
  }
}

// What the best leaves (left_best) against what the second leaves (left_second), both above
// the floor.
bool ties(double left_best, double left_second, const SelectionRules& rules) {
  const double apart = left_second - left_best;
  return apart < std::max(rules.tie_share * left_second, rules.tie_floor_share * rules.floor_mv);
}
}  // namespace

Effect constant_current_twin(Effect e) {
  switch (e) {
    case Effect::contact_resistance: return Effect::hysteresis;
    case Effect::hysteresis: return Effect::contact_resistance;
    case Effect::voltage_offset: return Effect::contact_resistance;
    case Effect::current_offset: return Effect::current_gain;
    case Effect::current_gain: return Effect::current_offset;
    default: break;
  }
  return Effect::none;
}

Selection select_effect(double none_mv, const std::vector<CandidateScore>& candidates, const SelectionRules& rules) {
  const CandidateScore* best = nullptr;
  const CandidateScore* second = nullptr;
  for (const auto& c : candidates) {
    if (!c.available || c.effect == Effect::none) continue;
    if (!best || c.heldout_rmse_mv < best->heldout_rmse_mv) {
      second = best;
      best = &c;
    } else if (!second || c.heldout_rmse_mv < second->heldout_rmse_mv) {
      second = &c;
    }
  }
  Selection s;
  if (!best) {
    s.reason = "no candidate effect available";
    return s;
  }
  s.best = best->effect;
  const double gain = none_mv - best->heldout_rmse_mv;
  auto excess = [&](double mv) { return std::sqrt(std::max(0.0, mv * mv - rules.floor_mv * rules.floor_mv)); };
  if (gain < rules.min_relative_gain * none_mv || gain < rules.min_absolute_gain_mv) {
    s.reason = fmt::format(
        "no candidate improves the held-out RMSE meaningfully: best {} {:.3f} mV vs {:.3f} mV without "
        "(needs a {:.0f} % and {:.2f} mV reduction)",
        effect_name(best->effect), best->heldout_rmse_mv, none_mv, 100.0 * rules.min_relative_gain,
        rules.min_absolute_gain_mv);
    return s;
  }
  if (second && ties(excess(best->heldout_rmse_mv), excess(second->heldout_rmse_mv), rules)) {
    s.identifiable = false;
    s.reason = fmt::format(
        "not identifiable: {} ({:.3f} mV) and {} ({:.3f} mV) explain the residual equally well "
        "(they leave {:.3f} and {:.3f} mV above the {:.3f} mV floor; held-out RMSE without an effect {:.3f} mV); "
        "the data do not separate them",
        effect_name(best->effect), best->heldout_rmse_mv, effect_name(second->effect), second->heldout_rmse_mv,
        excess(best->heldout_rmse_mv), excess(second->heldout_rmse_mv), rules.floor_mv, none_mv);
    return s;
  }
  if (rules.constant_current_only) {
    const int cls = twin_class(best->effect);
    for (const auto& c : candidates) {
      if (cls == 0 || c.effect == best->effect || twin_class(c.effect) != cls || !c.available) continue;
      if (none_mv - c.heldout_rmse_mv >= rules.min_relative_gain * none_mv) {
        s.identifiable = false;
        s.reason = fmt::format(
            "not identifiable from one constant current: {} ({:.3f} mV) and {} ({:.3f} mV) both explain the "
            "residual (held-out RMSE without an effect {:.3f} mV); data with other currents, rest or CV phases "
            "would separate them",
            effect_name(best->effect), best->heldout_rmse_mv, effect_name(c.effect), c.heldout_rmse_mv, none_mv);
        return s;
      }
    }
  }
  s.effect = best->effect;
  s.value = best->value;
  s.reason = fmt::format("{} cuts the held-out RMSE from {:.3f} to {:.3f} mV; next best {} {:.3f} mV",
                         effect_name(best->effect), none_mv, best->heldout_rmse_mv,
                         second ? effect_name(second->effect) : "-", second ? second->heldout_rmse_mv : none_mv);
  return s;
}

}  // namespace bms::diagnosis
