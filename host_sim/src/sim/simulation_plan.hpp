#pragma once
// A truth-model run as the commands describe it (simulate, hil, diagnose, the studies): the
// options, their checks, the plan and its execution. The command-line flags are app/simulate_options.
#include <cstdint>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "io/measured_profile.hpp"
#include "sim/cycler.hpp"
#include "sim/experiment.hpp"
#include "sim/measurement.hpp"

namespace bms {

struct SimulateOptions {
  std::string cell = "paper";
  std::string protocol = "cccv";
  std::string current_sign;  // csv:FILE only: discharge-positive | charge-positive ("" = by layout and data)
  int cycles = 1;
  double current_a = 2.5;
  double dt_s = 0.2;
  double noise_v_mv = 0.0, noise_i_ma = 0.0, noise_t_k = 0.0;
  std::uint64_t seed = 1;
  double ic_error_pct = 0.0;
  std::vector<std::string> effects;
  std::vector<std::string> set;  // hidden truth parameters NAME=VALUE (sim/truth_parameters.hpp)
  double v_min = -1.0, v_max = -1.0;  // < 0: from the cell
  double cv_end_current_a = 0.125;
  int points = 20, radial = 20;
  double rtol = 1e-6;
  bool quiet = false;
};

// A measured current beyond 4x the largest C-rate simulate accepts (a column in mA labelled
// [A]): InputError naming the file, sample and time. simulate's csv: and diagnose's records.
void check_record_currents(const std::string& source, const std::vector<double>& t_s,
                           const std::vector<double>& current_a, const CellParameters& cell);
nlohmann::json options_json(const SimulateOptions& o);

struct SimulateRun {
  SimulationResult result;
  Measured measured;
  CellParameters cell;           // the nominal cell --cell names (no --set value in it)
  nlohmann::json parameters;     // every hidden truth parameter and the value this run used
};

// What a run will do, checked: every option validated (InputError naming the option) before
// any long work.
struct SimulationPlan {
  SimulationConfig config;
  MeasurementModel sensor;
  CellParameters cell;        // the nominal cell --cell names
  nlohmann::json parameters;  // every hidden truth parameter and its value in this run
  bool driven = false;        // csv: a measured current drives the model
  Experiment experiment;      // when not driven
  MeasuredProfile profile;    // when driven
  double v_stop_low_v = 0.0, v_stop_high_v = 0.0;
};
SimulationPlan plan_simulation(const SimulateOptions& o);

// Runs a plan, handing every sample to `sink` as it is made. Throws RuntimeFailure.
SimulationResult execute_simulation(const SimulationPlan& plan, SampleSink& sink, const ProgressFn& progress);

// plan + execute with the whole run in memory (hil and the studies, which need it all).
SimulateRun run_simulation(const SimulateOptions& o, const ProgressFn& progress);

}  // namespace bms
