#pragma once
// The command-line flags of a truth-model run (simulate, hil, diagnose); what they describe and
// how a run is planned and executed is sim/simulation_plan.
#include <CLI/CLI.hpp>

#include "sim/simulation_plan.hpp"

namespace bms::app {

void register_simulate_options(CLI::App& sub, SimulateOptions& o);

}  // namespace bms::app
