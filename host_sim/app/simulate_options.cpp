#include "simulate_options.hpp"

#include <cmath>

#include "io/input_error.hpp"
#include "io/measured_profile.hpp"
#include "sim/cell_catalog.hpp"
#include "sim/truth_parameters.hpp"

namespace bms::app {

void register_simulate_options(CLI::App& sub, SimulateOptions& o) {
  sub.add_option("--cell", o.cell, "paper | aboutenergy | FILE.bpx.json")->capture_default_str();
  sub.add_option("--protocol", o.protocol,
                 "cccv (repeated CC-CV discharge/charge) or csv:FILE (drive with a measured current: "
                 "truth.csv or About:Energy 'Time [s],I[A],U[V]' format)")
      ->capture_default_str();
  sub.add_option("--cycles", o.cycles, "Number of CCCV cycles")->capture_default_str()->check(CLI::Range(1, 100000));
  sub.add_option("--current-a", o.current_a, "CC current magnitude (A)")->capture_default_str();
  sub.add_option("--dt", o.dt_s, "Output sample time (s)")->capture_default_str();
  sub.add_option("--noise-v-mv", o.noise_v_mv, "Voltage measurement noise, standard deviation (mV)")->capture_default_str();
  sub.add_option("--noise-i-ma", o.noise_i_ma, "Current measurement noise, standard deviation (mA)")->capture_default_str();
  sub.add_option("--seed", o.seed, "Noise seed")->capture_default_str();
  sub.add_option("--ic-error-pct", o.ic_error_pct,
                 "Initial-condition error P: scales c_e, theta_n, theta_p by (1 + P/100)")->capture_default_str();
  sub.add_option("--effect", o.effects,
                 "Undeclared effect NAME=VALUE (repeatable): contact_resistance (ohm), hysteresis (V, half the "
                 "gap between the charge and discharge OCV branches; starts on the charge branch), current_offset "
                 "(A), current_gain (relative), thermal (lumped thermal model with Arrhenius properties; VALUE = "
                 "heat-transfer coefficient to ambient in W/K, e.g. 0.05 for an 18650 in still air), particle_size (cathode "
                 "particle-size distribution: VALUE = log-space standard deviation sigma of a lognormal of radii, "
                 "3 populations, same surface area), particle_size_negative (the same for the anode; not with the side "
                 "reaction), none");
  sub.add_option("--set", o.set,
                 "Hidden truth parameter NAME=VALUE (repeatable; the truth only, never the estimator), e.g. "
                 "film_growth_scale=2, inventory_scale=0.97, temperature_k=288.15; `bmssim simulate --list-params` "
                 "lists every name with its nominal value, unit and range");
  sub.add_option("--v-min", o.v_min, "Lower voltage limit (V); default: the cell's");
  sub.add_option("--v-max", o.v_max, "Upper voltage limit (V); default: the cell's");
  sub.add_option("--cv-end-current-a", o.cv_end_current_a, "CV phases end below this current (A)")->capture_default_str();
  sub.add_option("--points", o.points, "Finite volumes per region (anode, separator, cathode)")->capture_default_str()->check(CLI::Range(2, 400));
  sub.add_option("--radial", o.radial, "Finite volumes per particle")->capture_default_str()->check(CLI::Range(3, 400));
  sub.add_option("--rtol", o.rtol, "IDA relative tolerance")->capture_default_str();
  sub.add_flag("--quiet", o.quiet, "No progress output");
}

nlohmann::json options_json(const SimulateOptions& o) {
  return {{"cell", o.cell}, {"protocol", o.protocol}, {"cycles", o.cycles}, {"current_a", o.current_a},
          {"dt_s", o.dt_s}, {"noise_v_mv", o.noise_v_mv}, {"noise_i_ma", o.noise_i_ma}, {"seed", o.seed},
          {"ic_error_pct", o.ic_error_pct}, {"effects", o.effects}, {"set", o.set},
          {"cv_end_current_a", o.cv_end_current_a}, {"points", o.points}, {"radial", o.radial}, {"rtol", o.rtol}};
}

namespace {

void require_finite(double v, const char* option) {
  if (!std::isfinite(v)) throw InputError(std::string(option) + ": must be a finite number");
}

}  // namespace

SimulateRun run_simulation(const SimulateOptions& o, const ProgressFn& progress) {
  require_finite(o.current_a, "--current-a");
  require_finite(o.dt_s, "--dt");
  if (!(o.dt_s > 0.0 && o.dt_s <= 3600.0)) throw InputError("--dt: must be in (0, 3600] s");
  if (o.noise_v_mv < 0.0 || o.noise_i_ma < 0.0) throw InputError("--noise-v-mv/--noise-i-ma: must be >= 0");
  if (!(o.rtol > 0.0 && o.rtol < 1e-2)) throw InputError("--rtol: must be in (0, 0.01)");

  const TruthSettings truth_settings = TruthSettings::parse(o.set);

  SimulateRun run;
  run.cell = load_cell(o.cell);
  run.parameters = truth_settings.values_json(run.cell);
  SimulationConfig cfg;
  cfg.cell = truth_settings.apply(run.cell);
  cfg.mesh = {o.points, o.points, o.points, o.radial};
  cfg.solver.rtol = o.rtol;
  cfg.dt_s = o.dt_s;
  cfg.temperature_k = cfg.cell.thermal.ambient_temperature_k;
  cfg.ic = perturbed_initial_conditions(cfg.cell, o.ic_error_pct);
  // Not from the cell: the initial conditions start a cell without side reaction film-free,
  // while a film set on it stays as a constant series resistance.
  cfg.ic.r_film_ohm_m2 = truth_settings.value(run.cell, "r_film_initial_ohm_m2");

  MeasurementModel meas;
  meas.noise_v_mv = o.noise_v_mv;
  meas.noise_i_ma = o.noise_i_ma;
  meas.seed = o.seed;
  for (const auto& e : o.effects) {
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
      if (value < 0.0) throw InputError("--effect contact_resistance: must be >= 0 ohm");
      cfg.effects.contact_resistance_ohm = value;
    } else if (name == "current_offset") {
      meas.current_offset_a = value;
    } else if (name == "current_gain") {
      if (std::abs(value) >= 0.5) throw InputError("--effect current_gain: must be within +-0.5");
      meas.current_gain = value;
    } else if (name == "hysteresis") {
      if (!(value >= 0.0 && value <= 0.5))
        throw InputError("--effect hysteresis: must be in [0, 0.5] V (half the gap between the branches)");
      cfg.effects.hysteresis_v = value;
    } else if (name == "thermal") {
      if (!(value > 0.0)) throw InputError("--effect thermal: heat-transfer coefficient must be > 0 W/K");
      cfg.effects.thermal_h_w_per_k = value;
    } else if (name == "particle_size" || name == "particle_size_negative") {
      const bool anode = name == "particle_size_negative";
      if (!(value >= 0.0 && value <= 1.5))
        throw InputError("--effect " + name + ": log-space standard deviation of the " +
                         (anode ? "anode" : "cathode") + " radius must be in [0, 1.5]");
      (anode ? cfg.effects.particle_size_negative_sigma : cfg.effects.particle_size_sigma) = value;
    } else if (name != "none") {
      throw InputError("--effect '" + name +
                       "': unknown; use contact_resistance, hysteresis, current_offset, current_gain, thermal, "
                       "particle_size, particle_size_negative or none");
    }
  }

  const double v_min = o.v_min >= 0.0 ? o.v_min : cfg.cell.lower_voltage_v;
  const double v_max = o.v_max >= 0.0 ? o.v_max : cfg.cell.upper_voltage_v;
  if (!(v_min < v_max))
    throw InputError("voltage limits inverted: --v-min " + std::to_string(v_min) + " V must be below --v-max " +
                     std::to_string(v_max) + " V");

  if (o.protocol == "cccv") {
    CccvProtocol p;
    p.cycles = o.cycles;
    p.current_a = o.current_a;
    p.v_min = v_min;
    p.v_max = v_max;
    p.cv_end_current_a = o.cv_end_current_a;
    run.result = run_cccv(cfg, p, progress);
  } else if (o.protocol.rfind("csv:", 0) == 0) {
    const auto profile = read_measured_profile(o.protocol.substr(4), ProfileColumns::truth);
    run.result = run_current_profile(cfg, profile.t_s, profile.current_a, v_min - 0.5, v_max + 0.5, progress);
  } else {
    throw InputError("--protocol '" + o.protocol + "': use cccv or csv:FILE");
  }
  run.measured = measure(run.result.samples, meas);
  return run;
}

}  // namespace bms::app
