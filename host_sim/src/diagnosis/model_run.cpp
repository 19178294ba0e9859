#include "diagnosis/model_run.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "io/input_error.hpp"
#include "sim/truth_parameters.hpp"

namespace bms::diagnosis {

namespace {
// The run stops only well outside the cell's window, so that the knee at the end of a
// discharge is scored instead of cut off.
constexpr double kStopMarginV = 0.5;
// Stoichiometries the start state may reach (the OCP tables end at 0 and 1).
constexpr double kStoichEdge = 2e-3;
// The profile drive's own step threshold (current_profile_run.cpp): such changes stay steps.
constexpr double kKeepStepShare = 0.25;

double electrode_capacity_ah(const CellParameters& cell, const ElectrodeParameters& e) {
  return kFaradayC_mol * cell.electrode_area_m2 * e.thickness_m * e.solid_fraction * e.max_concentration_mol_m3 /
         3600.0;
}

CellParameters with_parameters(const CellParameters& nominal, const Hypothesis& h) {
  std::vector<std::string> sets;
  for (const auto& s : h)
    if (knob_kind(s.effect) == KnobKind::parameter) sets.push_back(fmt::format("{}={:.17g}", truth_parameter_of(s.effect), s.value));
  if (sets.empty()) return nominal;
  return TruthSettings::parse(sets).apply(nominal);
}

}  // namespace

InitialConditions initial_state_at_depth(const CellParameters& cell, double depth_ah) {
  InitialConditions ic = default_initial_conditions(cell);
  ic.stoich_neg -= depth_ah / electrode_capacity_ah(cell, cell.negative);
  ic.stoich_pos += depth_ah / electrode_capacity_ah(cell, cell.positive);
  ic.stoich_neg = std::clamp(ic.stoich_neg, kStoichEdge, 1.0 - kStoichEdge);
  ic.stoich_pos = std::clamp(ic.stoich_pos, kStoichEdge, 1.0 - kStoichEdge);
  return ic;
}

double depth_from_rest_voltage(const CellParameters& cell, double v, std::string* note) {
  const InitialConditions ic0 = default_initial_conditions(cell);
  const double qn = electrode_capacity_ah(cell, cell.negative), qp = electrode_capacity_ah(cell, cell.positive);
  // Depth range that keeps both stoichiometries inside (edge, 1 - edge).
  const double lo = -std::min((1.0 - kStoichEdge - ic0.stoich_neg) * qn, (ic0.stoich_pos - kStoichEdge) * qp);
  const double hi = std::min((ic0.stoich_neg - kStoichEdge) * qn, (1.0 - kStoichEdge - ic0.stoich_pos) * qp);
  auto ocv = [&](double d) {
    return cell.positive.ocp_v->value(ic0.stoich_pos + d / qp) - cell.negative.ocp_v->value(ic0.stoich_neg - d / qn);
  };
  if (v >= ocv(lo) || v <= ocv(hi)) {
    const double d = v >= ocv(lo) ? lo : hi;
    if (note)
      *note = fmt::format("rest voltage {:.4f} V outside the model's open-circuit range {:.4f}..{:.4f} V: start at "
                          "its {} end",
                          v, ocv(hi), ocv(lo), d == lo ? "full" : "empty");
    return d;
  }
  double a = lo, b = hi;  // the open-circuit voltage falls with depth
  for (int it = 0; it < 100 && b - a > 1e-9; ++it) {
    const double m = 0.5 * (a + b);
    (ocv(m) > v ? a : b) = m;
  }
  return 0.5 * (a + b);
}

ModelRun run_model(const ModelSetup& setup, const Record& record, const Hypothesis& h) {
  SimulationConfig cfg;
  cfg.cell = with_parameters(setup.cell, h);
  cfg.mesh = setup.mesh;
  cfg.solver.rtol = setup.rtol;
  cfg.temperature_k = record.temperature_k.empty() ? cfg.cell.thermal.ambient_temperature_k
                                                   : record.temperature_k.front();
  cfg.cell.thermal.ambient_temperature_k = cfg.temperature_k;
  cfg.cell.thermal.initial_temperature_k = cfg.temperature_k;
  const double soc_shift = knob_value(h, Effect::initial_soc);
  const double capacity_ah = cfg.cell.nominal_capacity_ah > 0 ? cfg.cell.nominal_capacity_ah : 1.0;
  if (std::isfinite(record.initial_depth_ah) || soc_shift != 0.0)
    cfg.ic = initial_state_at_depth(cfg.cell, (std::isfinite(record.initial_depth_ah) ? record.initial_depth_ah : 0.0) -
                                                  soc_shift * capacity_ah);
  else
    cfg.ic = default_initial_conditions(cfg.cell);
  for (const auto& s : h)
    if (!set_model_effect(cfg.effects, s))
      throw RuntimeFailure(std::string("effect ") + effect_name(s.effect) + " is not in this build's truth model");
  std::vector<double> current = driving_current(h, record.current_a);
  if (setup.drive_tolerance_share > 0) {
    double imax = 0.0;
    for (double i : current) imax = std::max(imax, std::abs(i));
    current = simplified_current(record.t_s, current, setup.drive_tolerance_share * imax);
  }
  SimulationResult result;
  try {
    result = run_current_profile(cfg, record.t_s, current, cfg.cell.lower_voltage_v - kStopMarginV,
                                 cfg.cell.upper_voltage_v + kStopMarginV);
  } catch (const RuntimeFailure& e) {
    throw RuntimeFailure(record.source + ": " + e.what());
  }
  ModelRun run;
  run.voltage_v.assign(record.t_s.size(), std::numeric_limits<double>::quiet_NaN());
  // The cycler samples at the profile's own times, in order, so sample k is record row k.
  for (std::size_t k = 0; k < result.samples.size() && k < run.voltage_v.size(); ++k)
    run.voltage_v[k] = result.samples[k].voltage_v;
  run.samples_covered = std::min(result.samples.size(), run.voltage_v.size());
  run.note = result.note;
  run.wall_s = result.wall_s;
  return run;
}

std::vector<double> simplified_current(const std::vector<double>& t_s, const std::vector<double>& current_a,
                                       double tol_a) {
  const std::size_t n = t_s.size();
  double imax = 0.0;
  for (double i : current_a) imax = std::max(imax, std::abs(i));
  const double step_a = kKeepStepShare * imax;
  std::vector<double> out = current_a;
  std::size_t start = 0;
  double v0 = current_a.front();
  while (start + 1 < n) {
    if (std::abs(current_a[start + 1] - current_a[start]) > step_a) {  // a step stays a step
      v0 = current_a[++start];
      continue;
    }
    // The longest piece from `start` whose line stays within tol_a of every sample it spans.
    std::size_t best = start + 1;
    double lo = -HUGE_VAL, hi = HUGE_VAL;
    for (std::size_t end = start + 1; end < n && std::abs(current_a[end] - current_a[end - 1]) <= step_a; ++end) {
      const double dt = t_s[end] - t_s[start];
      const double nlo = std::max(lo, (current_a[end] - tol_a - v0) / dt);
      const double nhi = std::min(hi, (current_a[end] + tol_a - v0) / dt);
      if (nlo > nhi) break;
      lo = nlo;
      hi = nhi;
      best = end;
    }
    const double slope = std::clamp((current_a[best] - v0) / (t_s[best] - t_s[start]), lo, hi);
    for (std::size_t k = start + 1; k <= best; ++k) out[k] = v0 + slope * (t_s[k] - t_s[start]);
    v0 = out[best];
    start = best;
  }
  return out;
}

std::vector<double> residual_mv(const std::vector<double>& model_v, const Record& record) {
  std::vector<double> r(record.voltage_v.size(), 0.0);
  double last = 0.0;
  for (std::size_t k = 0; k < r.size(); ++k) {
    if (k < model_v.size() && std::isfinite(model_v[k])) last = 1e3 * (model_v[k] - record.voltage_v[k]);
    r[k] = last;
  }
  return r;
}

double rms(const std::vector<double>& x, const std::vector<char>& use) {
  double s = 0.0;
  std::size_t n = 0;
  for (std::size_t k = 0; k < x.size(); ++k) {
    if (!use.empty() && !use[k]) continue;
    s += x[k] * x[k];
    ++n;
  }
  return n ? std::sqrt(s / static_cast<double>(n)) : 0.0;
}

double max_abs(const std::vector<double>& x, const std::vector<char>& use) {
  double m = 0.0;
  for (std::size_t k = 0; k < x.size(); ++k)
    if (use.empty() || use[k]) m = std::max(m, std::abs(x[k]));
  return m;
}

}  // namespace bms::diagnosis
