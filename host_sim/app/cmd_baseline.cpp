// bmssim baseline: reference estimators of the film resistance (augmented-state EKF, per-cycle
// batch least squares) and the Cramer-Rao lower bound, on the firmware's reduced model.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include <fmt/format.h>

#include "baselines/baseline_output.hpp"
#include "baselines/baseline_run.hpp"
#include "bms/fw/model/paper_cell.hpp"
#include "commands.hpp"
#include "io/input_error.hpp"
#include "io/output_folder.hpp"
#include "sim/cell_catalog.hpp"
#include "sim/truth_output.hpp"

namespace bms::app {

namespace {
struct BaselineCli {
  std::string data, out, shape = "constant", update = "cc_charge";
  baselines::BaselineOptions o;
  double noise_v_mv = -1.0, noise_i_ma = -1.0, ic_error_pct = 0.0, ekf_model_error_mv = 0.3;
  bool quiet = false;
};

int run_baseline_command(BaselineCli& c) {
  if (c.shape != "constant" && c.shape != "linear")
    throw InputError("--batch-shape must be 'constant' or 'linear' (got '" + c.shape + "')");
  if (c.update != "cc_charge" && c.update != "cc")
    throw InputError("--ekf-update must be 'cc_charge' or 'cc' (got '" + c.update + "')");
  if (c.noise_v_mv >= 0.0 && !(c.noise_v_mv > 0.0))
    throw InputError("--noise-v-mv must be positive (the bound and the weights divide by it)");
  c.o.batch.linear = c.shape == "linear";
  c.o.ekf.model_error_v = c.ekf_model_error_mv * 1e-3;
  c.o.ekf.update_all_cc = c.update == "cc";
  c.o.sigma_v_v = c.noise_v_mv >= 0.0 ? c.noise_v_mv * 1e-3 : -1.0;
  c.o.sigma_i_a = c.noise_i_ma >= 0.0 ? c.noise_i_ma * 1e-3 : -1.0;
  const CellParameters cell = load_cell("paper");
  c.o.ic = perturbed_initial_conditions(cell, c.ic_error_pct);
  const EstimateData data = read_estimate_data(c.data);
  OutputFolder folder(c.out);
  if (!c.quiet) std::fprintf(stderr, "baseline: %s on %zu ticks of %s\n", c.o.method.c_str(), data.t_s.size(), c.data.c_str());
  const baselines::BaselineResult r = baselines::run_baseline(data, c.o);
  const std::filesystem::path dir = folder.staging();
  baselines::write_baseline_csv(dir / "estimates.csv", r);
  auto summary = baselines::baseline_summary_json(r, c.o);
  summary["options"]["ic_error_pct"] = c.ic_error_pct;
  summary["data"] = c.data;
  write_file_atomically(dir / "summary.json", summary.dump(2) + "\n");
  folder.commit();
  if (!c.quiet) {
    std::fprintf(stderr, "baseline: noise sigma_v %.4g mV (%s), sigma_i %.4g mA (%s)\n", r.noise.sigma_v_v * 1e3,
                 r.noise.v_source.c_str(), r.noise.sigma_i_a * 1e3, r.noise.i_source.c_str());
    for (const auto& b : r.bounds) {
      double med = std::nan(""), end = std::nan("");
      for (const auto& s : r.scores)
        if (s.cycle == b.cycle) med = s.r_film_err_median_pct, end = s.r_film_err_end_pct;
      std::fprintf(stderr, "baseline: cycle %d: film-resistance error in CC charge: median %.3f %%, end %.3f %%; "
                   "Cramer-Rao bound %.4f %%\n", b.cycle, med, end, b.rel_pct);
    }
    std::fprintf(stderr, "baseline: %zu ticks in %.2f s wall -> %s\n", r.rows.size(), r.wall_s,
                 (folder.destination() / "estimates.csv").c_str());
  }
  return 0;
}

}  // namespace

Runner add_baseline(CLI::App& app) {
  auto* sub = app.add_subcommand(
      "baseline",
      "Reference estimators of the SEI film resistance on the firmware's reduced model, to judge RCSI against: "
      "an augmented-state EKF (film resistance as a random-walk state), a per-cycle batch least-squares fit "
      "(accuracy ceiling), and the Cramer-Rao lower bound per cycle. Reads only the measured columns of a "
      "truth.csv (current_meas_a, voltage_meas_v); the truth columns only to score.");
  auto c = std::make_shared<BaselineCli>();
  sub->add_option("--data", c->data, "truth.csv written by 'bmssim simulate' (paper cell)")->required();
  sub->add_option("--method", c->o.method, "ekf | batch | crlb")->required();
  sub->add_option("--noise-v-mv", c->noise_v_mv,
                  "Voltage noise std [mV] the data are weighted with (default: estimated from second differences "
                  "of the CC-charge voltage, at least 0.02 mV)");
  sub->add_option("--noise-i-ma", c->noise_i_ma,
                  "Current noise std [mA] (default: estimated from first differences of the CC-charge current); "
                  "mapped to voltage through dV/dI of each tick");
  sub->add_option("--r-film-init", c->o.r_film_init_ohm_m2,
                  "Film resistance the EKF and the first batch cycle start from [ohm m2] (default: the paper cell's "
                  "initial film, " + fmt::format("{}", fw::paper::kInitialFilm_ohm_m2) + ")");
  sub->add_option("--ic-error-pct", c->ic_error_pct,
                  "Initial-condition error of the model (not the data), percent: scales the initial anode and "
                  "cathode stoichiometries and the electrolyte concentration together")
      ->capture_default_str();
  sub->add_option("--ekf-q-r", c->o.ekf.q_r_ohm_m2_per_sqrt_s, "EKF: random walk of R_film [ohm m2/sqrt(s)]")
      ->capture_default_str();
  sub->add_option("--ekf-q-conc", c->o.ekf.q_conc_rel_per_sqrt_s,
                  "EKF: model-error random walk of each concentration [fraction of its scale per sqrt(s)]")
      ->capture_default_str();
  sub->add_option("--ekf-p0-r", c->o.ekf.p0_r_rel, "EKF: initial std of R_film, relative")->capture_default_str();
  sub->add_option("--ekf-p0-conc", c->o.ekf.p0_conc_rel,
                  "EKF: initial std of each region's concentration (uniform shift), relative")
      ->capture_default_str();
  sub->add_option("--ekf-gate", c->o.ekf.gate_sigmas,
                  "EKF: skip updates whose innovation exceeds this many of its standard deviations (0: never)")
      ->capture_default_str();
  sub->add_option("--ekf-model-error-mv", c->ekf_model_error_mv,
                  "EKF: model error [mV std] added to the measurement noise (the reduced model's CC-charge error is "
                  "0.29 mV RMS against the truth)")
      ->capture_default_str();
  sub->add_option("--ekf-update", c->update,
                  "EKF: learn in 'cc_charge' only (like RCSI) or in 'cc' (CC charge and CC discharge)")
      ->capture_default_str();
  sub->add_option("--batch-shape", c->shape,
                  "Batch: film resistance per CC charge 'constant' or 'linear' in time")
      ->capture_default_str();
  sub->add_option("--out", c->out, "Output folder (estimates.csv, summary.json)")->required();
  sub->add_flag("--quiet", c->quiet, "No progress lines");
  sub->footer("Example: bmssim simulate --cycles 5 --noise-v-mv 0.2 --seed 1 --out out/sim5_v02 && "
              "bmssim baseline --data out/sim5_v02/truth.csv --method ekf --noise-v-mv 0.2 --out out/ekf_v02");
  return [c]() { return run_baseline_command(*c); };
}

}  // namespace bms::app
