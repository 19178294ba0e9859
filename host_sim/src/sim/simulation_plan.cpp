#include "sim/simulation_plan.hpp"

#include <cmath>

#include <fmt/format.h>

#include "io/input_error.hpp"
#include "io/measured_profile.hpp"
#include "sim/cell_catalog.hpp"
#include "sim/truth_parameters.hpp"

namespace bms {

nlohmann::json options_json(const SimulateOptions& o) {
  return {{"cell", o.cell}, {"protocol", o.protocol}, {"cycles", o.cycles}, {"current_a", o.current_a},
          {"dt_s", o.dt_s}, {"noise_v_mv", o.noise_v_mv}, {"noise_i_ma", o.noise_i_ma}, {"noise_t_k", o.noise_t_k}, {"seed", o.seed},
          {"ic_error_pct", o.ic_error_pct}, {"effects", o.effects}, {"set", o.set},
          {"cv_end_current_a", o.cv_end_current_a}, {"points", o.points}, {"radial", o.radial}, {"rtol", o.rtol}};
}

namespace {

void require_finite(double v, const char* option) {
  if (!std::isfinite(v)) throw InputError(std::string(option) + ": must be a finite number");
}

// Above this the truth's particles empty at the surface within seconds for the cells we carry;
// such a run ends in a solver failure instead of an answer.
constexpr double kMaxCRate = 5.0;
// The output grid: below 10 ms a cycle writes hundreds of millions of rows.
constexpr double kMinDtS = 0.01;
// A driven run stops this far outside the cell's window (a measured record may overshoot the
// limits a little; the model should not be stopped by what the cell survived).
constexpr double kDrivenStopMarginV = 0.5;
// The narrowest voltage window a cycle can run in: below it CC and CV alternate within the
// model's own tolerance.
constexpr double kMinWindowV = 0.05;

double open_circuit_voltage_v(const CellParameters& cell, const InitialConditions& ic) {
  return cell.positive.ocp_v->value(ic.stoich_pos) - cell.negative.ocp_v->value(ic.stoich_neg);
}

// The window must be wide, within the cell's own limits (0.5 V of slack), and hold the cell's
// starting open-circuit voltage; else the first step ends or fails at once.
void check_voltage_window(const CellParameters& cell, const InitialConditions& ic, double v_min, double v_max) {
  const double lo = cell.lower_voltage_v - 0.5, hi = cell.upper_voltage_v + 0.5;
  if (!(v_min >= lo && v_max <= hi))
    throw InputError(fmt::format("--v-min/--v-max [{:g}, {:g}] V: must lie within the cell's limits [{:g}, {:g}] V "
                                 "with 0.5 V of slack",
                                 v_min, v_max, cell.lower_voltage_v, cell.upper_voltage_v));
  if (!(v_max - v_min >= kMinWindowV))
    throw InputError(fmt::format("--v-min/--v-max [{:g}, {:g}] V: the window must be at least {:g} V wide", v_min,
                                 v_max, kMinWindowV));
  const double ocv = open_circuit_voltage_v(cell, ic);
  if (!(ocv > v_min && ocv < v_max))
    throw InputError(fmt::format("--v-min/--v-max [{:g}, {:g}] V: the cell starts at rest at {:.4f} V, outside the "
                                 "window",
                                 v_min, v_max, ocv));
}

// A measured current far beyond what the cell can carry is bad input, not a solver failure.
void check_profile_currents(const MeasuredProfile& p, const CellParameters& cell) {
  check_record_currents(p.source, p.t_s, p.current_a, cell);
}

void check_experiment(const Experiment& e, const CellParameters& cell, double v_min, double v_max) {
  for (const auto& step : e.steps) {
    const double c_rate = std::abs(step.value) / cell.nominal_capacity_ah;
    if (step.kind == ControlKind::current && c_rate > kMaxCRate)
      throw InputError(fmt::format("--protocol step '{}': {:g} A is {:.3g}C; at most {:g}C for this cell's {:g} Ah",
                                   step.text, std::abs(step.value), c_rate, kMaxCRate, cell.nominal_capacity_ah));
    // A step ending only on a voltage or current has no duration; the cycler bounds it at max_step_s.
    if (std::isfinite(step.duration_s) && step.duration_s > e.max_step_s)
      throw InputError(fmt::format("--protocol step '{}': {:g} s is longer than a step may run ({:g} s); split it "
                                   "into shorter steps",
                                   step.text, step.duration_s, e.max_step_s));
    const double v = step.kind == ControlKind::voltage ? step.value : step.until_voltage_v;
    if (std::isfinite(v) && !(v >= v_min - 0.5 && v <= v_max + 0.5))
      throw InputError(fmt::format("--protocol step '{}': {:g} V is outside the cell's window [{:g}, {:g}] V by more "
                                   "than 0.5 V",
                                   step.text, v, v_min, v_max));
  }
}

// The hysteresis branch starts on the charge side, H above the equilibrium: that must not put
// the resting cell above its upper limit.
void check_effects_fit_window(const SimulationConfig& cfg, double v_min, double v_max) {
  if (cfg.effects.hysteresis_v <= 0.0) return;
  const double ocv = open_circuit_voltage_v(cfg.cell, cfg.ic);
  if (ocv + cfg.effects.hysteresis_v >= v_max || ocv - cfg.effects.hysteresis_v <= v_min)
    throw InputError(fmt::format("--effect hysteresis={:g}: the resting cell ({:.4f} V) +- H leaves the window "
                                 "[{:g}, {:g}] V",
                                 cfg.effects.hysteresis_v, ocv, v_min, v_max));
}

// --effect NAME=VALUE into the truth's effects and the sensor model.
void apply_effect(const std::string& e, ModelEffects& effects, MeasurementModel& meas) {
  const auto eq = e.find('=');
  if (eq == std::string::npos) throw InputError("--effect '" + e + "': expected NAME=VALUE");
  const std::string name = e.substr(0, eq);
  double value = 0.0;
  try {
    size_t used = 0;
    value = std::stod(e.substr(eq + 1), &used);
    if (used != e.size() - eq - 1) throw std::invalid_argument("trailing");
  } catch (const std::exception&) {
    throw InputError("--effect '" + e + "': VALUE must be a number");
  }
  if (!std::isfinite(value)) throw InputError("--effect '" + e + "': VALUE must be a finite number");
  if (name == "contact_resistance") {
    if (!(value >= 0.0 && value <= 1.0)) throw InputError("--effect contact_resistance: must be in [0, 1] ohm");
    effects.contact_resistance_ohm = value;
  } else if (name == "current_offset") {
    if (!(std::abs(value) <= 10.0)) throw InputError("--effect current_offset: must be within +-10 A");
    meas.current_offset_a = value;
  } else if (name == "current_gain") {
    if (std::abs(value) >= 0.5) throw InputError("--effect current_gain: must be within +-0.5");
    meas.current_gain = value;
  } else if (name == "temperature_offset") {
    if (!(std::abs(value) <= 50.0)) throw InputError("--effect temperature_offset: must be within +-50 K");
    meas.temperature_offset_k = value;
  } else if (name == "voltage_offset") {
    if (!(std::abs(value) <= 0.1)) throw InputError("--effect voltage_offset: must be within +-0.1 V");
    meas.voltage_offset_v = value;
  } else if (name == "hysteresis") {
    if (!(value >= 0.0 && value <= 0.5))
      throw InputError("--effect hysteresis: must be in [0, 0.5] V (half the gap between the branches)");
    effects.hysteresis_v = value;
  } else if (name == "thermal") {
    if (!(value > 0.0 && value <= 1e3)) throw InputError("--effect thermal: heat-transfer coefficient must be in (0, 1000] W/K");
    effects.thermal_h_w_per_k = value;
  } else if (name == "particle_size" || name == "particle_size_negative") {
    const bool anode = name == "particle_size_negative";
    if (!(value >= 0.0 && value <= 1.5))
      throw InputError("--effect " + name + ": log-space standard deviation of the " +
                       (anode ? "anode" : "cathode") + " radius must be in [0, 1.5]");
    (anode ? effects.particle_size_negative_sigma : effects.particle_size_sigma) = value;
  } else if (name == "diffusivity_profile_positive") {
    if (!(value >= -4.0 && value <= 2.0))
      throw InputError("--effect diffusivity_profile_positive: log10 of the factor at full lithiation must be in [-4, 2]");
    effects.diffusivity_profile_positive = value;
  } else if (name == "diffusivity_profile_positive_knee") {
    if (!(value >= 0.0 && value <= 0.99))
      throw InputError("--effect diffusivity_profile_positive_knee: the knee stoichiometry must be in [0, 0.99]");
    effects.diffusivity_profile_positive_knee = value;
  } else if (name == "resistive_reactant_positive") {
    if (!(value >= 0.0 && value <= 100.0))
      throw InputError("--effect resistive_reactant_positive: the resistance below the knee must be in [0, 100] ohm m2");
    effects.resistive_reactant_positive_ohm_m2 = value;
  } else if (name == "resistive_reactant_positive_log10") {
    if (!(value >= 0.0 && value <= 6.0))
      throw InputError("--effect resistive_reactant_positive_log10: decades of rise to full lithiation must be in [0, 6]");
    effects.resistive_reactant_positive_log10 = value;
  } else if (name == "resistive_reactant_positive_knee") {
    if (!(value >= 0.0 && value <= 0.99))
      throw InputError("--effect resistive_reactant_positive_knee: the knee stoichiometry must be in [0, 0.99]");
    effects.resistive_reactant_positive_knee = value;
  } else if (name == "resistive_reactant_positive_ea") {
    if (!(value >= 0.0 && value <= 2e5))
      throw InputError("--effect resistive_reactant_positive_ea: the activation energy must be in [0, 200000] J/mol");
    effects.resistive_reactant_positive_ea_j_mol = value;
  } else if (name != "none") {
    throw InputError("--effect '" + name +
                     "': unknown; use contact_resistance, hysteresis, current_offset, current_gain, temperature_offset, voltage_offset, thermal, "
                     "particle_size, particle_size_negative, diffusivity_profile_positive, diffusivity_profile_positive_knee, "
                     "resistive_reactant_positive, resistive_reactant_positive_log10, resistive_reactant_positive_knee, "
                     "resistive_reactant_positive_ea or none");
  }
}

// The CC current, CV end current and voltage window of a cccv run, against the cell.
void check_cccv_options(const SimulateOptions& o, const CellParameters& cell, const InitialConditions& ic,
                        double v_min, double v_max) {
  const double c_rate = cell.nominal_capacity_ah > 0.0 ? o.current_a / cell.nominal_capacity_ah : 0.0;
  if (!(o.current_a > 0.0) || c_rate > kMaxCRate)
    throw InputError("--current-a " + fmt::format("{:g}", o.current_a) + " A: must be positive and at most " +
                     fmt::format("{:g}", kMaxCRate) + "C (" + fmt::format("{:.3g}", kMaxCRate * cell.nominal_capacity_ah) +
                     " A for this cell's " + fmt::format("{:g}", cell.nominal_capacity_ah) + " Ah)");
  if (!(o.cv_end_current_a > 0.0 && o.cv_end_current_a < o.current_a))
    throw InputError("--cv-end-current-a " + fmt::format("{:g}", o.cv_end_current_a) +
                     " A: must be positive and below the CC current " + fmt::format("{:g}", o.current_a) + " A");
  check_voltage_window(cell, ic, v_min, v_max);
}

}  // namespace

void check_record_currents(const std::string& source, const std::vector<double>& t_s,
                           const std::vector<double>& current_a, const CellParameters& cell) {
  const double limit_a = 4.0 * kMaxCRate * cell.nominal_capacity_ah;
  for (size_t i = 0; i < current_a.size(); ++i)
    if (!(std::abs(current_a[i]) <= limit_a))
      throw InputError(fmt::format("{}: sample {} (t = {:g} s): current {:g} A is beyond {:g}C ({:g} A) for this "
                                   "cell's {:g} Ah (a column in mA labelled [A]?)",
                                   source, i + 1, t_s[i], current_a[i], 4.0 * kMaxCRate, limit_a,
                                   cell.nominal_capacity_ah));
}

SimulationPlan plan_simulation(const SimulateOptions& o) {
  require_finite(o.current_a, "--current-a");
  require_finite(o.dt_s, "--dt");
  if (!(o.dt_s >= kMinDtS && o.dt_s <= 3600.0))
    throw InputError(fmt::format("--dt {:g}: must be in [{:g}, 3600] s", o.dt_s, kMinDtS));
  if (!(o.noise_v_mv >= 0.0 && o.noise_v_mv <= 1e3) || !(o.noise_i_ma >= 0.0 && o.noise_i_ma <= 1e5))
    throw InputError("--noise-v-mv/--noise-i-ma: must be in [0, 1000] mV / [0, 100000] mA");
  if (!(o.noise_t_k >= 0.0 && o.noise_t_k <= 50.0)) throw InputError("--noise-t-k: must be in [0, 50] K");
  if (!(o.rtol > 0.0 && o.rtol < 1e-2)) throw InputError("--rtol: must be in (0, 0.01)");

  const TruthSettings truth_settings = TruthSettings::parse(o.set);
  SimulationPlan plan;
  plan.cell = load_cell(o.cell);
  plan.parameters = truth_settings.values_json(plan.cell);
  SimulationConfig& cfg = plan.config;
  cfg.cell = truth_settings.apply(plan.cell);
  cfg.mesh = {o.points, o.points, o.points, o.radial};
  cfg.solver.rtol = o.rtol;
  cfg.dt_s = o.dt_s;
  cfg.temperature_k = cfg.cell.thermal.ambient_temperature_k;
  cfg.ic = perturbed_initial_conditions(cfg.cell, o.ic_error_pct);
  // Not from the cell: the initial conditions start a cell without side reaction film-free,
  // while a film set on it stays as a constant series resistance.
  cfg.ic.r_film_ohm_m2 = truth_settings.value(plan.cell, "r_film_initial_ohm_m2");

  plan.sensor.noise_v_mv = o.noise_v_mv;
  plan.sensor.noise_i_ma = o.noise_i_ma;
  plan.sensor.noise_t_k = o.noise_t_k;
  plan.sensor.seed = o.seed;
  for (const auto& e : o.effects) apply_effect(e, cfg.effects, plan.sensor);

  const double v_min = o.v_min >= 0.0 ? o.v_min : cfg.cell.lower_voltage_v;
  const double v_max = o.v_max >= 0.0 ? o.v_max : cfg.cell.upper_voltage_v;
  if (!(v_min < v_max))
    throw InputError("voltage limits inverted: --v-min " + std::to_string(v_min) + " V must be below --v-max " +
                     std::to_string(v_max) + " V");
  if (!o.current_sign.empty() && o.protocol.rfind("csv:", 0) != 0)
    throw InputError("--current-sign: only with --protocol csv:FILE (the sign of the file's current)");
  if (o.protocol == "cccv") {
    check_cccv_options(o, cfg.cell, cfg.ic, v_min, v_max);
    CccvProtocol p;
    p.cycles = o.cycles;
    p.current_a = o.current_a;
    p.v_min = v_min;
    p.v_max = v_max;
    p.cv_end_current_a = o.cv_end_current_a;
    plan.experiment = cccv_experiment(p);
  } else if (o.protocol.rfind("csv:", 0) == 0) {
    plan.driven = true;
    plan.profile = read_measured_profile(o.protocol.substr(4), ProfileColumns::truth, current_sign_option(o.current_sign));
    check_profile_currents(plan.profile, cfg.cell);
    plan.v_stop_low_v = v_min - kDrivenStopMarginV;
    plan.v_stop_high_v = v_max + kDrivenStopMarginV;
  } else {
    plan.experiment = parse_experiment(o.protocol, cfg.cell.nominal_capacity_ah, o.cycles);
    check_voltage_window(cfg.cell, cfg.ic, v_min, v_max);
    check_experiment(plan.experiment, cfg.cell, v_min, v_max);
  }
  check_effects_fit_window(cfg, v_min, v_max);
  return plan;
}

SimulationResult execute_simulation(const SimulationPlan& plan, SampleSink& sink, const ProgressFn& progress) {
  if (!plan.driven) return run_experiment(plan.config, plan.experiment, sink, progress);
  SimulationResult r = run_current_profile(plan.config, plan.profile.t_s, plan.profile.current_a, plan.v_stop_low_v,
                                           plan.v_stop_high_v, progress);
  for (const auto& s : r.samples) sink.on_sample(s);
  for (const auto& c : r.cycles) sink.on_cycle(c);
  r.samples.clear();
  r.samples.shrink_to_fit();
  return r;
}

SimulateRun run_simulation(const SimulateOptions& o, const ProgressFn& progress) {
  const SimulationPlan plan = plan_simulation(o);
  SimulateRun run;
  run.cell = plan.cell;
  run.parameters = plan.parameters;
  std::vector<SampleRecord> samples;
  SampleCollector sink(samples);
  run.result = execute_simulation(plan, sink, progress);
  run.result.samples = std::move(samples);
  run.measured = measure(run.result.samples, plan.sensor);
  return run;
}

}  // namespace bms
