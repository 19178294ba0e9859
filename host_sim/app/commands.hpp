#pragma once
// bmssim subcommands: each registers its options on the CLI app and returns a runner.
#include <functional>

#include <CLI/CLI.hpp>

namespace bms::app {

using Runner = std::function<int()>;  // returns the process exit code

Runner add_simulate(CLI::App& app);
Runner add_validate(CLI::App& app);
Runner add_estimate(CLI::App& app);
Runner add_hil(CLI::App& app);
Runner add_study(CLI::App& app);
Runner add_baseline(CLI::App& app);
Runner add_diagnose(CLI::App& app);
Runner add_cell_config(CLI::App& app);
Runner add_fit(CLI::App& app);

}  // namespace bms::app
