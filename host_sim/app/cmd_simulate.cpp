// bmssim simulate: the truth model through a protocol, with the measurement model.
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <unistd.h>

#include "commands.hpp"
#include "io/input_error.hpp"
#include "io/measured_profile.hpp"
#include "sim/cell_catalog.hpp"
#include "sim/truth_parameters.hpp"
#include "simulate_options.hpp"
#include "sim/truth_output.hpp"

namespace bms::app {

Runner add_simulate(CLI::App& app) {
  auto* sub = app.add_subcommand("simulate", "Run the truth model (full DFN + Ramadass side reaction)");
  auto opts = std::make_shared<SimulateOptions>();
  register_simulate_options(*sub, *opts);
  auto out_dir = std::make_shared<std::string>();
  auto* out = sub->add_option("--out", *out_dir, "Output folder (truth.csv, summary.json)")->required();
  auto list_params = std::make_shared<bool>(false);
  // Option callbacks run before CLI11 checks required options: listing needs no --out.
  sub->add_flag_callback(
      "--list-params",
      [list_params, out]() {
        *list_params = true;
        out->required(false);
      },
      "Print every --set NAME with its nominal value for --cell, unit and range, one per line, and exit");
  sub->footer(
      "Example: bmssim simulate --cell paper --protocol cccv --cycles 5 --out out/sim\n"
      "         bmssim simulate --cell aboutenergy --protocol csv:LFP_25degC_1C.csv --out out/ae1c\n"
      "         bmssim simulate --cell paper --cycles 1 --set film_growth_scale=2 --set inventory_scale=0.98 --out out/hidden\n"
      "         bmssim simulate --cell paper --list-params");
  return [opts, out_dir, list_params]() {
    if (*list_params) {
      std::fputs(truth_parameter_listing(load_cell(opts->cell)).c_str(), stdout);
      return 0;
    }
    const bool tty = isatty(STDERR_FILENO) != 0;
    auto progress = [tty](double t, int cycle, Mode mode) {
      std::fprintf(stderr, tty ? "\rsimulate: t = %8.0f s, cycle %d, %-12s" : "simulate: t = %.0f s, cycle %d, %s\n",
                   t, cycle, mode_name(mode));
    };
    const SimulateRun run = run_simulation(*opts, opts->quiet ? ProgressFn{} : ProgressFn(progress));
    if (tty && !opts->quiet) std::fprintf(stderr, "\n");
    std::filesystem::create_directories(*out_dir);
    const std::filesystem::path dir(*out_dir);
    write_truth_csv(dir / "truth.csv", run.result, run.measured);
    auto summary = summary_json(run.result);
    summary["options"] = options_json(*opts);
    summary["parameters"] = run.parameters;
    write_file_atomically(dir / "summary.json", summary.dump(2) + "\n");
    if (!opts->quiet) {
      std::fprintf(stderr, "simulate: %.0f s simulated in %.2f s wall (%zu samples) -> %s\n", run.result.sim_s,
                   run.result.wall_s, run.result.samples.size(), (dir / "truth.csv").c_str());
      if (!run.result.note.empty()) std::fprintf(stderr, "simulate: note: %s\n", run.result.note.c_str());
    }
    return 0;
  };
}

}  // namespace bms::app
