#include "diagnosis/model_run.hpp"

#include <cmath>
#include <limits>

#include "io/input_error.hpp"
#include "sim/cycler.hpp"

namespace bms::diagnosis {

namespace {
// The run stops only well outside the cell's window, so that the knee at the end of a
// discharge is scored instead of cut off.
constexpr double kStopMarginV = 0.5;
}  // namespace

ModelRun run_model(const ModelSetup& setup, const Record& record, const EffectSetting& effect) {
  SimulationConfig cfg;
  cfg.cell = setup.cell;
  cfg.mesh = setup.mesh;
  cfg.solver.rtol = setup.rtol;
  cfg.temperature_k = record.temperature_k.empty() ? cfg.cell.thermal.ambient_temperature_k
                                                   : record.temperature_k.front();
  cfg.cell.thermal.ambient_temperature_k = cfg.temperature_k;
  cfg.cell.thermal.initial_temperature_k = cfg.temperature_k;
  cfg.ic = default_initial_conditions(cfg.cell);
  if (!set_model_effect(cfg.effects, effect))
    throw RuntimeFailure(std::string("effect ") + effect_name(effect.effect) + " is not in this build's truth model");
  const std::vector<double> current = driving_current(effect, record.current_a);
  const auto result = run_current_profile(cfg, record.t_s, current, cfg.cell.lower_voltage_v - kStopMarginV,
                                          cfg.cell.upper_voltage_v + kStopMarginV);
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
