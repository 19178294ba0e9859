// bmssim simulate: the truth model through a protocol, with the measurement model.
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <unistd.h>

#include "commands.hpp"
#include "io/atomic_file.hpp"
#include "io/input_error.hpp"
#include "io/output_folder.hpp"
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
    const SimulationPlan plan = plan_simulation(*opts);  // bad input: exit 2 before any work
    OutputFolder folder(*out_dir);
    const bool tty = isatty(STDERR_FILENO) != 0;
    auto progress = [tty](double t, int cycle, Mode mode) {
      std::fprintf(stderr, tty ? "\rsimulate: t = %8.0f s, cycle %d, %-12s" : "simulate: t = %.0f s, cycle %d, %s\n",
                   t, cycle, mode_name(mode));
    };
    TruthCsvStream truth(folder.staging() / "truth.csv", plan.sensor);
    SimulationResult result;
    std::string failure;
    try {
      result = execute_simulation(plan, truth, opts->quiet ? ProgressFn{} : ProgressFn(progress));
    } catch (const WriteFailure&) {
      throw;  // the disk: nothing can be kept
    } catch (const RuntimeFailure& e) {
      failure = e.what();  // keep what was finished, marked incomplete
    }
    if (tty && !opts->quiet) std::fprintf(stderr, "\n");
    if (!failure.empty()) {
      result.cycles = truth.cycles();
      result.sim_s = truth.last().t_s;
    }
    truth.commit();
    auto summary = summary_json(result);
    summary["samples"] = truth.samples();
    summary["complete"] = failure.empty();
    if (!failure.empty()) summary["failure"] = failure;
    summary["options"] = options_json(*opts);
    summary["parameters"] = plan.parameters;
    write_file_atomically(folder.staging() / "summary.json", summary.dump(2) + "\n");
    folder.commit();
    const std::filesystem::path dir = folder.destination();
    if (!failure.empty()) {
      std::fprintf(stderr,
                   "bmssim simulate: %s\n  kept %zu finished cycle(s) and %ld samples in %s (summary.json says "
                   "\"complete\": false); try a smaller current, a wider window or --rtol 1e-7\n",
                   failure.c_str(), truth.cycles().size(), truth.samples(), dir.c_str());
      return 1;
    }
    if (!opts->quiet) {
      std::fprintf(stderr, "simulate: %.0f s simulated in %.2f s wall (%ld samples) -> %s\n", result.sim_s,
                   result.wall_s, truth.samples(), (dir / "truth.csv").c_str());
      if (!result.note.empty()) std::fprintf(stderr, "simulate: note: %s\n", result.note.c_str());
    }
    return 0;
  };
}

}  // namespace bms::app
