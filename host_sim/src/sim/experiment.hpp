#pragma once
// A cycling experiment as PyBaMM writes one ("Discharge at 1C until 2.0 V; Rest for 30
// minutes; Charge at 2.5 A until 3.6 V; Hold at 3.6 V until 50 mA"), parsed into steps the
// cycler runs. `cccv` is the named experiment of this kind that the paper's studies use.
#include <limits>
#include <string>
#include <vector>

#include "dfn/dfn_model.hpp"
#include "sim/cycler.hpp"

namespace bms {

struct ExperimentStep {
  Mode mode = Mode::rest;
  ControlKind kind = ControlKind::current;
  double value = 0.0;  // current in A (positive = discharge) or held voltage in V
  // Ends: whichever comes first. NaN / < 0 / infinity: not watched.
  double until_voltage_v = std::numeric_limits<double>::quiet_NaN();
  double until_abs_current_a = -1.0;
  double duration_s = std::numeric_limits<double>::infinity();
  std::string text;  // the step as written, for messages
};

struct Experiment {
  std::vector<ExperimentStep> steps;  // one cycle
  int cycles = 1;
  double max_step_s = 6.0 * 3600.0;  // safety net for a step with no time limit
};

// The paper's cycle: CC discharge to v_min, CV there to the end current, CC charge to v_max,
// CV there to the end current. Throws InputError when the limits or currents cannot work.
Experiment cccv_experiment(const CccvProtocol& protocol);

// Parses `text` (steps split by ';', case-insensitive, PyBaMM's wording: "Discharge|Charge at
// X A|mA|C|C/N [for D unit] [until V V|or until V V]", "Rest for D unit", "Hold at V V until
// I A|mA|C/N [or for D]", unit of D one of seconds, minutes, hours). C rates use
// `capacity_ah`. Throws InputError naming the step and what is wrong.
Experiment parse_experiment(const std::string& text, double capacity_ah, int cycles);

}  // namespace bms
