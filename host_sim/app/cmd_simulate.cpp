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
#include "simulate_options.hpp"
#include "sim/truth_output.hpp"

namespace bms::app {

Runner add_simulate(CLI::App& app) {
  auto* sub = app.add_subcommand("simulate", "Run the truth model (full DFN + Ramadass side reaction)");
  auto opts = std::make_shared<SimulateOptions>();
  register_simulate_options(*sub, *opts);
  auto out_dir = std::make_shared<std::string>();
  sub->add_option("--out", *out_dir, "Output folder (truth.csv, summary.json)")->required();
  sub->footer(
      "Example: bmssim simulate --cell paper --protocol cccv --cycles 5 --out out/sim\n"
      "         bmssim simulate --cell aboutenergy --protocol csv:LFP_25degC_1C.csv --out out/ae1c");
  return [opts, out_dir]() {
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
