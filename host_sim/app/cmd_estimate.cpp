// bmssim estimate: the firmware's tick (BmsCore, same code as on target) run offline on a file.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include "bms/fw/fw_status.hpp"
#include "commands.hpp"
#include "estimation/aging_report.hpp"
#include "estimation/charges.hpp"
#include "estimation/cycler_input.hpp"
#include "estimation/estimate_output.hpp"
#include "estimation/estimate_run.hpp"
#include "io/input_error.hpp"
#include "io/output_folder.hpp"
#include "sim/cell_catalog.hpp"
#include "sim/truth_output.hpp"

namespace bms::app {

namespace {

// An estimate from data the firmware rejected sample by sample is no estimate: say so.
void require_accepted_samples(const EstimateResult& r, const std::string& data) {
  constexpr auto rejected = static_cast<std::uint32_t>(fw::FwStatus::kSampleNonFinite) |
                            static_cast<std::uint32_t>(fw::FwStatus::kVoltageOutOfRange) |
                            static_cast<std::uint32_t>(fw::FwStatus::kCurrentImplausible);
  std::size_t accepted = 0;
  for (const auto& row : r.rows) accepted += (row.status & rejected) == 0 ? 1 : 0;
  if (accepted == 0)
    throw RuntimeFailure(data + ": the firmware rejected every one of its " + std::to_string(r.rows.size()) +
                         " samples (non-finite, voltage outside 0-5 V or an implausible current): check the file's "
                         "columns and units (V, A, discharge positive)");
}
struct EstimateCli {
  std::vector<std::string> data;
  std::string out, cell = "paper", current_sign;
  EstimateOptions o;
  double ic_error_pct = 0.0;
  bool beyond = false;
  bool quiet = false;
  std::vector<std::string> model_effects;
};

// summary.json: the estimator's summary, and no errors for a file without truth.
nlohmann::json command_summary(const EstimateResult& r, const EstimateOptions& o, const EstimateData& data) {
  nlohmann::json summary = estimate_summary_json(r, o);
  summary["truth"] = data.has_truth();
  if (!data.has_truth()) {
    // A measured file: what the estimator learned, and no error (there is nothing to compare with).
    summary["note"] = "no truth in the data: the estimates are reported without errors";
    for (auto& cy : summary["cycles"]) {
      cy["r_film_err_median_pct"] = nullptr;
      cy["r_film_err_end_pct"] = nullptr;
      cy["r_film_true_end_ohm_m2"] = nullptr;
      cy["inventory_err_end_pct"] = nullptr;
    }
    summary["data_layout"] = data.layout_note;
  }
  const auto& fx = o.model_effects;
  summary["options"]["model_effects"] =
      o.model_effects_on ? nlohmann::json{{"contact_resistance_ohm", fx.contact_resistance_ohm},
                                          {"hysteresis_v", fx.hysteresis_v},
                                          {"current_offset_a", fx.current_offset_a},
                                          {"current_gain", fx.current_gain}}
                         : nlohmann::json::object();
  return summary;
}

void print_scores(const EstimateResult& r, const EstimateData& data, const std::string& data_path,
                  const std::filesystem::path& destination) {
  if (!data.has_truth())
    std::fprintf(stderr, "estimate: no truth in %s (%s): estimates without errors\n", data_path.c_str(),
                 data.layout_note.c_str());
  for (const auto& cs : r.cycles)
    if (data.has_truth()) std::fprintf(stderr,
                 "estimate: cycle %d: film-resistance error in CC charge: median %.3f %%, end %.3f %%; "
                 "inventory error at its end %.4f %%\n",
                 cs.cycle, cs.r_film_err_median_pct, cs.r_film_err_end_pct, cs.inventory_err_end_pct);
  if (std::isfinite(r.growth_err_pct)) std::fprintf(stderr, "estimate: growth_err_pct %.2f %%\n", r.growth_err_pct);
  std::fprintf(stderr, "estimate: %zu ticks in %.2f s wall -> %s\n", r.rows.size(), r.wall_s,
               (destination / "estimates.csv").c_str());
}

// The contract's `charges`; from a cycler's exports, also the comparison with the cycler's own
// per-cycle capacity and resistance (aging.csv, capacity.png, resistance.png).
void add_charges(nlohmann::json& summary, const EstimateResult& r, const EstimateInput& input,
                 const CellParameters& cell, const std::filesystem::path& dir, bool quiet) {
  const std::vector<ChargeReport> charges = find_charges(r.rows, input.data, cell);
  summary["charges"] = charges_json(charges);
  summary["charges_note"] =
      "capacity_ah: charge counted on the measured current over each charge (CC and CV), not yet the estimator's "
      "own capacity; r_film_sd_ohm_m2: null, the estimator reports no film uncertainty yet; r_step_ohm: the voltage "
      "step at the charge's onset over the current";
  if (input.cycler_cycles.empty()) return;
  // Every CC charge the mode detector found, learned in or not (a control run learns in none).
  const AgingComparison a = compare_aging(find_charges(r.rows, input.data, cell, false), input.cycler_cycles);
  summary["aging"] = aging_json(a);
  const std::string problem = write_aging_outputs(dir, a);
  if (!problem.empty()) {
    summary["aging"]["plots"] = problem;
    if (!quiet) std::fprintf(stderr, "estimate: %s\n", problem.c_str());
  }
}

int run_estimate_command(EstimateCli& c, const CLI::App& sub) {
  c.o.mesh.n_sep = c.o.mesh.n_pos = c.o.mesh.n_neg;
  const auto given = [&sub](const char* flag) { return sub.count(flag) > 0; };
  if (c.beyond) {
    if (given("--settings")) throw InputError("--beyond-paper is the session-5 profile; give it or --settings, not both");
    c.o.settings = "beyond-paper";
    apply_beyond_paper(c.o, given);
  } else {
    apply_settings(c.o, given);
  }
  for (const auto& e : c.model_effects) add_model_effect(c.o, e);
  if (given("--r-film-init") && !(std::isfinite(c.o.r_film_init_ohm_m2) && c.o.r_film_init_ohm_m2 >= 0.0 &&
                                  c.o.r_film_init_ohm_m2 <= 1.0))
    throw InputError("--r-film-init: must be a finite film resistance in [0, 1] ohm m2");
  const CellParameters cell = load_cell(c.cell);
  c.o.ic = perturbed_initial_conditions(cell, c.ic_error_pct);
  const CurrentSign sign = current_sign_option(c.current_sign);
  const EstimateInput input = read_estimate_input(c.data, sign);
  const EstimateData& data = input.data;
  const bool quiet = c.quiet;
  auto progress = [quiet](std::size_t row, std::size_t rows) {
    if (!quiet) std::fprintf(stderr, "estimate: %zu / %zu ticks\n", row, rows);
  };
  OutputFolder folder(c.out);
  const EstimateResult r = run_estimate(data, cell, c.o, progress);
  require_accepted_samples(r, input.label);
  const std::filesystem::path dir = folder.staging();
  write_estimates_csv(dir / "estimates.csv", r, data.has_truth());
  nlohmann::json summary = command_summary(r, c.o, data);
  add_charges(summary, r, input, cell, dir, quiet);
  write_file_atomically(dir / "summary.json", summary.dump(2) + "\n");
  folder.commit();
  if (!quiet) print_scores(r, data, input.label, folder.destination());
  return 0;
}

}  // namespace

// Long on purpose: a table of the command's option declarations (CLI11), one option per
// statement, read as a list; cutting it in parts would only scatter the options of one command.
Runner add_estimate(CLI::App& app) {
  auto* sub = app.add_subcommand(
      "estimate",
      "Run the firmware estimator (RCSI of the SEI film resistance) offline on a truth.csv: reads only the "
      "measured columns (current_meas_a, voltage_meas_v); the truth columns are used only to score.");
  auto c = std::make_shared<EstimateCli>();
  sub->add_option("--data", c->data,
                  "truth.csv written by 'bmssim simulate', or a measured file (About:Energy 'Time [s],I[A],U[V]' or "
                  "any CSV with time, current and voltage columns picked by name; no truth, so no errors), or a "
                  "cycler's exports (Arbin, Maccor, Neware, BioLogic .mpt, NASA PCoE): repeat --data or give a folder "
                  "for the files of one cell, joined in time order")
      ->required()
      ->take_all();
  sub->add_option("--current-sign", c->current_sign,
                  "discharge-positive | charge-positive: the sign of a measured file's current (default: by its "
                  "layout; cycler files charge-positive)");
  sub->add_option("--model", c->o.model,
                  "Main-system model: 'reduced' (the firmware's reduced-order DFN) or 'full' (the truth DFN without "
                  "film growth: the paper's setting)")
      ->capture_default_str();
  sub->add_option("--settings", c->o.settings,
                  "Estimator profile: 'best' (the project's best, from the nominal cell only: the film, its growth "
                  "gain and the lithium inventory identified together; BmsCore::best_config) or 'paper' (the paper's "
                  "RCSI: n_c = 1, eta = 0, P(0) = 5e-7 I, H = 0.01). Options given explicitly beside it win")
      ->capture_default_str();
  sub->add_flag("!--no-learning", c->o.learning,
                "Control run: the same settings with every RCSI / RLS update switched off (what the nominal cell "
                "alone predicts)");
  sub->add_flag("!--no-inventory", c->o.learn_inventory,
                "With --settings best: keep the nominal lithium inventory instead of identifying it (ablation)");
  sub->add_option("--model-bias-ohm", c->o.model_bias_ohm,
                  "With --settings best: the main model's voltage bias in CC charge per ampere [ohm] (default: the "
                  "reduced model's design-time calibration, 0 for the full model; 0 = ablation)");
  sub->add_option("--theta0", c->o.theta0,
                  "RCSI's theta(0) = M1..Mnc,N1..Nnc (comma-separated; default 1,0: hold the film at a charge start; "
                  "0,0 is what the paper's figure 6 suggests)")
      ->delimiter(',');
  sub->add_option("--relinearise", c->o.relinearise_inventory,
                  "With --settings best: a re-synchronisation that moves the model's inventory by more than this "
                  "(relative) restarts the film's learning (1 = never: ablation)")
      ->check(CLI::Range(0.0, 1.0))
      ->capture_default_str();
  sub->add_option("--cell", c->cell, "Cell of the main model: paper | aboutenergy | FILE.bpx.json")->capture_default_str();
  sub->add_option("--nc", c->o.nc, "Order n_c of the ARX subsystem model (1..8)")->capture_default_str();
  sub->add_option("--p0", c->o.p0, "RLS initial covariance P(0) = p0 I (paper: 5e-7)")->capture_default_str();
  sub->add_option("--p0-y0", c->o.p0_y0, "P(0) for the side-current regressors when it should differ from --p0 "
                  "(regressors of very different size: ohm m2 vs A/m3)");
  sub->add_option("--lambda", c->o.lambda, "RLS forgetting factor in (0, 1]")->capture_default_str();
  sub->add_option("--eta", c->o.eta, "Retrospective-cost regularisation eta >= 0 (paper: 0)")->capture_default_str();
  sub->add_option("--h", c->o.h_v_per_ohm_m2, "Markov parameter H [V per ohm m2] (paper: 0.01)")->capture_default_str();
  sub->add_flag("--h-from-model", c->o.markov_from_model,
                "Use H = dV/dR_film of the main model at each charge start (about 0.88 for the paper cell) instead of --h");
  sub->add_option("--r-film-init", c->o.r_film_init_ohm_m2,
                  "Film resistance the estimator starts from [ohm m2] (default: the cell's initial value)");
  sub->add_option("--ic-error-pct", c->ic_error_pct,
                  "Initial-condition error of the main model (not the data), percent: scales the initial anode and "
                  "cathode stoichiometries and the electrolyte concentration together (paper: +-1)")
      ->capture_default_str();
  sub->add_flag("--resync", c->o.resync,
                "Beyond the paper: re-synchronise the firmware model's state at the end of each CV phase (measured "
                "voltage, nominal lithium inventory minus the model's lithium loss) and once at the first sample "
                "(power-up from rest); removes initial-condition errors");
  sub->add_flag("!--no-start-resync", c->o.resync_at_start,
                "With --resync: skip the re-synchronisation at the first sample (only at CV ends, as in session 3)");
  sub->add_option("--resync-window", c->o.resync_window_ticks,
                  "With --resync: ticks of measured voltage and current each re-synchronisation fits a straight line "
                  "to (evaluated at the last tick), against measurement noise; 1 = the trigger sample alone")
      ->check(CLI::Range(1u, 3000u))
      ->capture_default_str();
  sub->add_option("--resync-current", c->o.resync_current_a,
                  "|current| [A] below which a CV phase counts as ended for --resync")
      ->capture_default_str();
  sub->add_option("--warmup", c->o.warmup_s,
                  "Beyond the paper: seconds at the start of each CC charge before RCSI learns (film held)")
      ->capture_default_str();
  sub->add_flag("--calibrate-bias", c->o.calibrate_bias,
                "Beyond the paper: the first CC charge is a reference charge at the initial film resistance; its mean "
                "residual (after --warmup) is the model's voltage bias, subtracted in later charges");
  sub->add_option("--reference-after-resyncs", c->o.reference_after_resyncs,
                  "With --resync and --calibrate-bias: re-synchronisations before the reference charge")
      ->capture_default_str();
  sub->add_flag("--average", c->o.average_estimate,
                "Beyond the paper: report and hold the mean of RCSI's u_hat over each charge's learning window");
  sub->add_flag("--propagate-growth", c->o.propagate_growth,
                "Beyond the paper: the reported film resistance follows the growth the model's side current "
                "predicts (Ramadass law, the cell's constants) between and within RCSI's updates; RCSI sets the level");
  sub->add_option("--inventory-error-pct", c->o.inventory_error_pct,
                  "With --resync: the lithium inventory the re-synchronisation assumes is off the cell's nominal one "
                  "by this percent (how well a BMS must know its cell's inventory)")
      ->capture_default_str();
  sub->add_option("--growth-scale", c->o.growth_scale,
                  "With --propagate-growth: factor on the growth law, to test a cell whose film constants differ "
                  "from the model's (1 = the model's own)")
      ->capture_default_str();
  sub->add_flag("--beyond-paper", c->beyond,
                "Shorthand for the firmware's best settings, BmsCore::beyond_paper_config (docs/results/firmware-model.md): "
                "--h-from-model --p0 5e-7 --resync --resync-window 50 --warmup 600 --calibrate-bias --average "
                "--propagate-growth; an option given explicitly beside it wins (e.g. --resync-window 1, "
                "--growth-scale 0 for an ablation)");
  sub->add_option("--model-effect", c->model_effects,
                  "Add an effect to the main model NAME=VALUE (repeatable; e.g. the one 'bmssim diagnose' found): "
                  "contact_resistance (ohm), hysteresis (V, half the gap between the OCV branches; starts on the "
                  "charge branch), current_offset (A, what the sensor reads at zero current), current_gain (relative). "
                  "Default: none (the paper's model)");
  sub->add_option("--points", c->o.mesh.n_neg, "Full model: finite volumes per region")->capture_default_str();
  sub->add_option("--out", c->out, "Output folder (estimates.csv, summary.json)")->required();
  sub->add_flag("--quiet", c->quiet, "No progress lines");
  sub->footer("Example: bmssim simulate --cycles 5 --out out/sim && bmssim estimate --data out/sim/truth.csv "
              "--model reduced --out out/est");
  return [c, sub]() { return run_estimate_command(*c, *sub); };
}

}  // namespace bms::app
