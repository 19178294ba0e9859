// bmssim estimate: the firmware's tick (BmsCore, same code as on target) run offline on a file.
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "bms/fw/estimation/fw_status.hpp"
#include "commands.hpp"
#include "estimation/aging_report.hpp"
#include "estimation/charges.hpp"
#include "estimation/cycler_input.hpp"
#include "estimation/estimate_output.hpp"
#include "cell/reduced_cell_record.hpp"
#include "estimation/design_bias.hpp"
#include "estimation/estimate_run.hpp"
#include "estimation/film_bound.hpp"
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
                         " samples (non-finite, a voltage outside the cell's window by more than " + std::to_string(fw::kVoltagePlausibilityMarginV).substr(0, 3) + " V, or an implausible current): check the file's "
                         "columns and units (V, A, discharge positive)");
}
struct EstimateCli {
  std::vector<std::string> data;
  std::string out, cell = "paper", current_sign, settings = "best";
  EstimateOptions o;
  std::vector<double> theta0;
  double ic_error_pct = 0.0;
  bool beyond = false;
  bool quiet = false;
  bool write_stream = false;  // --write-firmware-stream
  double bound_noise_v_mv = 0.0;  // --bound-noise-v-mv (scoring only; 0: no bound)
  std::vector<std::string> model_effects;
};

// Which overrides the user gave: the flag's count, after CLI11 has stored the values.
void mark_given(const CLI::App& sub, EstimateCli& c) {
  fw::Overrides& v = c.o.overrides;
  const auto g = [&sub](const char* flag, auto& field) { field.given = sub.count(flag) > 0; };
  g("--nc", v.nc);
  g("--h", v.h_v_per_ohm_m2);
  g("--h-from-model", v.h_from_model);
  g("--p0", v.p0);
  g("--p0-y0", v.p0_y0);
  g("--lambda", v.lambda);
  g("--eta", v.eta);
  g("--r-film-init", v.r_film_init_ohm_m2);
  g("--calibrate-bias", v.calibrate_bias);
  g("--reference-after-resyncs", v.reference_after_resyncs);
  g("--average", v.average_estimate);
  g("--propagate-growth", v.propagate_growth);
  g("--growth-scale", v.growth_scale);
  g("--no-learning", v.learning);
  g("--warmup", v.warmup_s);
  g("--resync", v.resync);
  g("--no-start-resync", v.resync_at_start);
  g("--resync-window", v.resync_window_ticks);
  g("--resync-current", v.resync_current_a);
  g("--resync-settle-s", v.resync_settle_s);
  g("--no-inventory", v.learn_inventory);
  g("--model-bias-ohm", v.model_bias_ohm);
  g("--no-bias-table", v.model_bias_table);
  g("--no-bias-levels", v.model_bias_levels);
  g("--bias-table-any-start", v.bias_table_any_start);
  g("--no-charge-coverage", v.charge_coverage);
  g("--no-trusted-span", v.trusted_span);
  g("--trusted-span-end", v.trusted_span_end);
  g("--relinearise", v.relinearise_inventory);
  g("--no-hold", v.hold_until_settled);
  g("--hold-restarted-charge", v.hold_restarted_charge);
  g("--innovation-reject", v.innovation_rejects);
  g("--innovation-gate", v.innovation_gate);
  g("--misfit-stop-s", v.misfit_stop_s);
  g("--inventory-sd", v.inventory_sd);
  g("--spread-anode-i0", v.spread_anode_i0_rel);
  g("--spread-cathode-i0", v.spread_cathode_i0_rel);
  g("--spread-transport", v.spread_transport_rel);
  g("--spread-area", v.spread_area_rel);
  g("--fuse-level-only", v.fuse_level_only);
  g("--film-initial-sd", v.film_initial_sd_rel);
  g("--voltage-offset-sd-mv", v.voltage_offset_sd_mv);
  g("--current-gain-sd-pct", v.current_gain_sd_pct);
  g("--no-current-offset", v.current_offset);
  g("--voltage-offset", v.voltage_offset);
  g("--no-area-scale", v.area_scale);
  g("--area-scale-in-model", v.area_scale_model_sees);
  g("--inventory-error-pct", c.o.inventory_error_pct);
  c.o.points_given = sub.count("--points") > 0;
  if (sub.count("--theta0") > 0) {
    if (c.theta0.size() > 16) throw InputError("--theta0: at most 16 values (n_c <= 8)");
    fw::Theta0 t{};
    t.count = static_cast<int>(c.theta0.size());
    for (std::size_t k = 0; k < c.theta0.size(); ++k) t.values[k] = c.theta0[k];
    v.theta0 = t;
  }
}

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
  if (std::isfinite(r.model_bias_ohm)) summary["model_bias_used_ohm"] = r.model_bias_ohm;
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
      "capacity_ah, capacity_sd_ah: the estimator's open-circuit capacity and 1-sigma at the CC end "
      "(capacity_source 'estimator'), or where it identifies none the charge counted on the measured current over "
      "the charge (CC and CV; capacity_source 'counted'); counted_ah: that counted charge always; r_film_sd_ohm_m2: "
      "the estimator's 1-sigma (null where it has none); r_step_ohm: the voltage step at the charge's onset over the "
      "current";
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

// The bound is the best profile's (its H, S and G per tick): refused for another, and for a
// noise that is no standard deviation, before any long work.
void check_bound_option(const EstimateCli& c, const CLI::App& sub) {
  if (sub.count("--bound-noise-v-mv") == 0) return;
  if (!(c.bound_noise_v_mv > 0.0) || !std::isfinite(c.bound_noise_v_mv))
    throw InputError(fmt::format("--bound-noise-v-mv must be a noise standard deviation > 0 mV (got {})",
                                 c.bound_noise_v_mv));
  if (c.o.profile != fw::Profile::best)
    throw InputError("--bound-noise-v-mv is the bound of --settings best's unknowns; the settings given identify others");
}

int run_estimate_command(EstimateCli& c, const CLI::App& sub) {
  c.o.mesh.n_sep = c.o.mesh.n_pos = c.o.mesh.n_neg;
  if (c.beyond && sub.count("--settings") > 0)
    throw InputError("--beyond-paper is --settings nominal-growth; give one of them, not both");
  const std::string settings = c.beyond ? "nominal-growth" : c.settings;
  if (!fw::parse_profile(settings.c_str(), c.o.profile))
    throw InputError("--settings must be 'best', 'paper' or 'nominal-growth' (got '" + settings + "')");
  mark_given(sub, c);
  check_bound_option(c, sub);
  for (const auto& e : c.model_effects) add_model_effect(c.o, e);
  check_estimate_options(c.o);  // before any long work: an option the settings do not use exits 2
  const CellParameters cell = load_cell(c.cell);
  adopt_cell_effects(c.o, cell, c.model_effects);
  c.o.ic = perturbed_initial_conditions(cell, c.ic_error_pct);
  if (c.o.model == "reduced" && cell.name != "paper") {
    // A cell other than the paper's: refuse a file the firmware's model cannot use (naming the
    // field) before any long work, then its design-time bias from its nominal DFN (recorded in
    // summary.json as model_bias_used_ohm).
    (void)make_reduced_cell_record(cell);
    if (c.o.profile == fw::Profile::best && !c.o.overrides.model_bias_ohm.given)
      use_design_bias(c.o, design_time_bias(cell));
  }
  const CurrentSign sign = current_sign_option(c.current_sign);
  const EstimateInput input = read_estimate_input(c.data, sign);
  const EstimateData& data = input.data;
  require_sampling_for_learning(data, c.o.overrides.learning.or_else(true));
  const bool quiet = c.quiet;
  auto progress = [quiet](std::size_t row, std::size_t rows) {
    if (!quiet) std::fprintf(stderr, "estimate: %zu / %zu ticks\n", row, rows);
  };
  OutputFolder folder(c.out);
  const EstimateResult r = run_estimate(data, cell, c.o, progress);
  require_accepted_samples(r, input.label);
  const std::filesystem::path dir = folder.staging();
  write_estimates_csv(dir / "estimates.csv", r, data.has_truth());
  if (c.write_stream)
    write_file_atomically(dir / "firmware_stream.bin", firmware_stream(data, c.o.overrides.learning.or_else(true)));
  nlohmann::json summary = command_summary(r, c.o, data);
  if (c.bound_noise_v_mv > 0.0) {
    summary["crlb"] = film_bound_json(film_cramer_rao(r.rows, c.bound_noise_v_mv * 1e-3));
    summary["crlb"]["noise_v_mv"] = c.bound_noise_v_mv;
  }
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
  sub->add_option("--settings", c->settings,
                  "Estimator profile (bms/fw/config/make_config.hpp, the firmware's own): 'best' (from the nominal cell "
                  "only: the film, its growth gain and the lithium inventory identified together), 'paper' (the "
                  "paper's RCSI: n_c = 1, eta = 0, P(0) = " + fmt::format("{}", fw::kPaperCovarianceP0) +
                      " I, H = " + fmt::format("{}", fw::kPaperMarkovVPerOhmM2) +
                      ") or 'nominal-growth' (RCSI with the observer, bias calibration and the nominal growth "
                      "law). The options below change the profile; one it does not use exits 2 naming it")
      ->capture_default_str();
  sub->add_flag("--beyond-paper", c->beyond, "The same as --settings nominal-growth (its older name)");
  sub->add_flag("!--no-learning", c->o.overrides.learning.value,
                "Control run: the same settings with every RCSI / RLS update switched off (what the nominal cell "
                "alone predicts)");
  sub->add_option("--warmup", c->o.overrides.warmup_s.value,
                  "Seconds at the start of each CC charge before the estimator learns (film held; default: the "
                  "profile's, paper 0, best 900, nominal-growth 600)");
  // best only: the FilmGrowthIdentifier.
  sub->add_flag("!--no-inventory", c->o.overrides.learn_inventory.value,
                "--settings best only: keep the nominal lithium inventory instead of identifying it (ablation)");
  sub->add_option("--model-bias-ohm", c->o.overrides.model_bias_ohm.value,
                  "--settings best only: the main model's voltage bias in CC charge per ampere [ohm] (default: the "
                  "reduced model's design-time calibration, 0 for the full model; 0 = ablation)");
  sub->add_flag("!--no-bias-table", c->o.overrides.model_bias_table.value,
                "--settings best only: remove the reduced model's design-time bias as the constant alone, not with "
                "its state-of-charge-dependent table (a cell other than the paper's; the paper cell has no table)");
  sub->add_flag("!--no-bias-levels", c->o.overrides.model_bias_levels.value,
                "--settings best only: read the design-time bias table calibrated at the nominal lithium inventory "
                "alone, not interpolated between its levels 1 % below and above at the model's identified inventory "
                "(ablation)");
  sub->add_flag("--bias-table-any-start", c->o.overrides.bias_table_any_start.value,
                "--settings best only: apply the design-time bias table in every CC charge, also one whose learning "
                "opens more than a tenth of the table's span above where its calibration's charges opened (a partial "
                "charge begun mid-window, where the table's history does not hold; by default such a charge runs on "
                "the constant bias alone; ablation)");
  sub->add_flag("!--no-charge-coverage", c->o.overrides.charge_coverage.value,
                "--settings best only: learn in every CC charge, also one the design-time calibration does not "
                "cover: a charge current below the lowest one at which the calibration's bias fits the nominal cell, "
                "or a charge that runs on the constant bias alone where the constant does not fit it (by default "
                "such a charge is not learned from; the film goes on with its growth law; ablation)");
  sub->add_flag("!--no-trusted-span", c->o.overrides.trusted_span.value,
                "--settings best only: learn in the whole CC charge, also past the design-time calibration's "
                "trusted span (where the reduced model leaves the nominal cell: a flat-OCP cell's end-of-charge "
                "knee; ablation)");
  sub->add_option("--trusted-span-end", c->o.overrides.trusted_span_end.value,
                  "--settings best only: the model's mean anode stoichiometry above which a CC charge's learning "
                  "stops (default: the design-time calibration's; none for the paper cell)")
      ->check(CLI::Range(0.0, 1.0));
  sub->add_option("--relinearise", c->o.overrides.relinearise_inventory.value,
                  "--settings best with the observer: a re-synchronisation that moves the model's inventory by more "
                  "than this (relative, default 1e-3) restarts the film's learning (1 = never: ablation)")
      ->check(CLI::Range(0.0, 1.0));
  sub->add_flag("!--no-hold", c->o.overrides.hold_until_settled.value,
                "--settings best only: report the identifier's film, parameters and capacity from the first "
                "learning tick after the start or a relinearisation, not the prior's (held, propagated) until the "
                "restarted fit has settled (ablation: the first seconds swing tens of percent)");
  sub->add_flag("--hold-restarted-charge", c->o.overrides.hold_restarted_charge.value,
                "--settings best only: hold a restarted fit's outputs through the whole CC charge it restarts in, "
                "not only until it settles (helps under a current gain; off by default: where the inventory "
                "settles over several charges each charge then reports the previous one's end)");
  sub->add_option("--innovation-reject", c->o.overrides.innovation_rejects.value,
                  "--settings best only: on|off, whether a learning tick whose regression innovation (the residual "
                  "less what the fitted film, gain and inventory explain), averaged over 60 s, fails the innovation "
                  "gate (5 x 0.3 mV) is left out of the fit, as PX4 EKF2 rejects a fusion");
  sub->add_option("--innovation-gate", c->o.overrides.innovation_gate.value,
                  "--settings best only: the innovation test's gate in units of the model's stated residual "
                  "(0.3 mV; default 5): the reported test and, with --innovation-reject on, the fusion's check")
      ->check(CLI::Range(0.5, 100.0));
  sub->add_option("--misfit-stop-s", c->o.overrides.misfit_stop_s.value,
                  "--settings best only: the stop condition of a charge's fusion: once the residual less the "
                  "design-time bias and less what the fitted inventory explains has failed the innovation gate "
                  "for more than this many seconds of a CC charge's learning within the trusted span, the fit the "
                  "charge started with did not explain it: the fit goes back to the last one a charge verified (the "
                  "prior before any) and learns nothing more in that charge. A charge is tested when its starting "
                  "fit is settled or a stop has fired before (default 0: never stopped; 120 was chosen on "
                  "About:Energy's spread and protocol truths)")
      ->check(CLI::Range(0.0, 1e6));
  sub->add_option("--inventory-sd", c->o.overrides.inventory_sd.value,
                  "--settings best only: the cell's stated lithium-inventory tolerance (relative 1-sigma, e.g. "
                  "0.00577 for +-1 % uniform; default 0: not tested). A fit whose inventory leaves 3 of these is "
                  "not plausible (the film and inventory run together where the model's kinetics are not the "
                  "cell's; tested at each charge's start): the fit goes back to the last one a charge verified (the "
                  "prior before any) and learns nothing more until a restart")
      ->check(CLI::Range(0.0, 0.05));
  const std::string spread =
      "--settings best only: the cell's stated spread (a lot tolerance, relative 1-sigma in [0, 0.9], default 0: "
      "a characterised cell) of ";
  const std::string spread_end = "; its film equivalent enters r_film_sd_ohm_m2 in quadrature";
  sub->add_option("--spread-anode-i0", c->o.overrides.spread_anode_i0_rel.value,
                  spread + "the anode's exchange current" + spread_end);
  sub->add_option("--spread-cathode-i0", c->o.overrides.spread_cathode_i0_rel.value,
                  spread + "the cathode's exchange current" + spread_end);
  sub->add_option("--spread-transport", c->o.overrides.spread_transport_rel.value,
                  spread + "each transport property (electrolyte conductivity and diffusivity, each electrode's solid "
                           "diffusivity, independently)" + spread_end);
  sub->add_option("--spread-area", c->o.overrides.spread_area_rel.value,
                  spread + "the electrode area (both electrodes' capacity)" + spread_end);
  sub->add_flag("--fuse-level-only", c->o.overrides.fuse_level_only.value,
                "--settings best with a stated spread: combine the prior with the fitted film's level alone and "
                "report the fit's growth on top (a spread offsets a cell's level, not its growth), not with the "
                "whole fitted film; helps where the fitted growth is good (the paper cell), not where it is not "
                "(off by default)");
  sub->add_option("--film-initial-sd", c->o.overrides.film_initial_sd_rel.value,
                  "--settings best only: the cell's stated tolerance of its initial film (a lot tolerance, "
                  "relative 1-sigma of the nominal film in [0, 0.9], e.g. 0.1155 for +-20 % uniform; default 0: "
                  "the regression's weak prior, 29 % of the paper cell's film). It is the prior's initial-film sd "
                  "wherever the prior is reported: held before a fit settles, and combined with the fit under a "
                  "stated spread (--spread-*), whose level is then the prior's with this sd, not the weak "
                  "prior's; the fit itself is unchanged");
  sub->add_option("--voltage-offset-sd-mv", c->o.overrides.voltage_offset_sd_mv.value,
                  "--settings best only: the voltage sensor's stated offset accuracy (the front end's datasheet "
                  "1-sigma in mV, in [0, 10], default 0); in CC charge an offset reads as film, so this over "
                  "dV/dR_film enters r_film_sd_ohm_m2 in quadrature");
  sub->add_option("--current-gain-sd-pct", c->o.overrides.current_gain_sd_pct.value,
                  "--settings best only: the current sensor's stated gain accuracy (the front end's datasheet "
                  "1-sigma in percent, in [0, 5], default 0); the capacity is counted in the sensor's amperes, so "
                  "this times the capacity enters capacity_sd_ah in quadrature");
  sub->add_flag("!--no-current-offset", c->o.overrides.current_offset.value,
                "Do not remove the current sensor's offset (default with --settings best: measured between two CV "
                "end points of the same kind, where the cell is in the same state, as the counted charge over the "
                "span's duration, when no two samples are more than 0.5 s apart; ablation)");
  sub->add_flag("--voltage-offset", c->o.overrides.voltage_offset.value,
                "--settings best only, experimental (off by default): remove a voltage sensor offset measured from "
                "each CC discharge's residual after a fitted CC charge (the film's drop has the other sign there, "
                "an offset the same); a change outside 0.1 mV restarts the film's learning. Misled by a current "
                "gain or a transport spread (docs/results/envelope.md)");
  sub->add_flag("!--no-area-scale", c->o.overrides.area_scale.value,
                "Do not measure the electrode-capacity (area) scale (default with --settings best: the counted "
                "charge between two CV ends against the model's pinned anode; the capacity is a times the "
                "nominal electrodes'; ablation)");
  sub->add_flag("--area-scale-in-model", c->o.overrides.area_scale_model_sees.value,
                "Run the model on I / a with the measured electrode-capacity scale a too (default: the capacity "
                "only; the film and growth were worse with it on the blind sensor set)");
  // RCSI (paper, nominal-growth).
  sub->add_option("--nc", c->o.overrides.nc.value, "RCSI profiles: order n_c of the ARX subsystem model (1..8, default 1)");
  sub->add_option("--p0", c->o.overrides.p0.value,
                  "RCSI profiles: RLS initial covariance P(0) = p0 I (default: the paper's " +
                      fmt::format("{}", fw::kPaperCovarianceP0) + ")");
  sub->add_option("--p0-y0", c->o.overrides.p0_y0.value,
                  "RCSI profiles: P(0) for the side-current regressors when it should differ from --p0 "
                  "(regressors of very different size: ohm m2 vs A/m3)");
  sub->add_option("--lambda", c->o.overrides.lambda.value, "RCSI profiles: RLS forgetting factor in (0, 1] (default 1)");
  sub->add_option("--eta", c->o.overrides.eta.value, "RCSI profiles: retrospective-cost regularisation eta >= 0 (default: the paper's 0)");
  sub->add_option("--theta0", c->theta0,
                  "RCSI profiles: theta(0) = M1..Mnc,N1..Nnc (comma-separated, 2 n_c values; default 1,0: hold the "
                  "film at a charge start; 0,0 is what the paper's figure 6 suggests)")
      ->delimiter(',');
  sub->add_option("--h", c->o.overrides.h_v_per_ohm_m2.value,
                  "--settings paper: Markov parameter H [V per ohm m2] (default: the paper's " +
                      fmt::format("{}", fw::kPaperMarkovVPerOhmM2) + "); the other profiles take H from the model");
  sub->add_flag("--h-from-model", c->o.overrides.h_from_model.value,
                "Use H = dV/dR_film of the main model at each charge start (about 0.88 for the paper cell) instead "
                "of --h (best and nominal-growth do already)");
  sub->add_option("--r-film-init", c->o.overrides.r_film_init_ohm_m2.value,
                  "RCSI profiles: film resistance the estimator starts from [ohm m2] (default: the cell's initial value)");
  sub->add_flag("--calibrate-bias", c->o.overrides.calibrate_bias.value,
                "RCSI profiles: the first CC charge is a reference charge at the initial film resistance; its mean "
                "residual (after --warmup) is the model's voltage bias, subtracted in later charges (nominal-growth: on)");
  sub->add_option("--reference-after-resyncs", c->o.overrides.reference_after_resyncs.value,
                  "With the bias calibration and the observer: re-synchronisations before the reference charge "
                  "(default 1)");
  sub->add_flag("--average", c->o.overrides.average_estimate.value,
                "RCSI profiles: report and hold the mean of RCSI's u_hat over each charge's learning window "
                "(nominal-growth: on)");
  sub->add_flag("--propagate-growth", c->o.overrides.propagate_growth.value,
                "RCSI profiles: the reported film resistance follows the growth the model's side current predicts "
                "(the nominal cell's Ramadass law) between and within RCSI's updates; RCSI sets the level "
                "(nominal-growth: on)");
  sub->add_option("--growth-scale", c->o.overrides.growth_scale.value,
                  "With the growth propagated: factor on the nominal growth law (default 1), to test a cell whose "
                  "film constants differ from the model's");
  // The state observer (best and nominal-growth on the reduced model; --resync for paper).
  sub->add_flag("--resync,!--no-resync", c->o.overrides.resync.value,
                "Re-synchronise the firmware model's state at the end of each CV phase (measured voltage, nominal "
                "lithium inventory minus the model's lithium loss) and once at the first sample (power-up from "
                "rest); reduced model only (best and nominal-growth: on; --no-resync switches it off)");
  sub->add_flag("!--no-start-resync", c->o.overrides.resync_at_start.value,
                "With the observer: skip the re-synchronisation at the first sample (only at CV ends)");
  sub->add_option("--resync-window", c->o.overrides.resync_window_ticks.value,
                  "With the observer: ticks of measured voltage and current each re-synchronisation fits a straight "
                  "line to (evaluated at the last tick), against measurement noise; 1 = the trigger sample alone "
                  "(default: paper 1, best and nominal-growth 50)")
      ->check(CLI::Range(1u, 3000u));
  sub->add_option("--resync-current", c->o.overrides.resync_current_a.value,
                  "With the observer: |current| [A] below which a CV phase counts as ended (default 0.25)");
  sub->add_option("--resync-settle-s", c->o.overrides.resync_settle_s.value,
                  "With the observer: a record that begins under a current (above --resync-current) is "
                  "re-synchronised at power-up only after this many seconds, once the first seconds' "
                  "transients, where the reduced model and the cell differ by tens of mV, have passed; at "
                  "rest at once (default 30; 0: at the first sample, the ablation)")
      ->check(CLI::Range(0.0, 1e6));
  sub->add_option("--inventory-error-pct", c->o.inventory_error_pct.value,
                  "Reduced model with the observer or --settings best: the lithium inventory the estimator assumes "
                  "is off the cell's nominal one by this percent (how well a BMS must know its cell's inventory)");
  sub->add_option("--cell", c->cell, "Cell of the main model: paper | aboutenergy | lco | nmc | FILE.bpx.json")->capture_default_str();
  sub->add_option("--ic-error-pct", c->ic_error_pct,
                  "Initial-condition error of the main model (not the data), percent: scales the initial anode and "
                  "cathode stoichiometries and the electrolyte concentration together (paper: +-1)")
      ->capture_default_str();
  sub->add_option("--model-effect", c->model_effects,
                  "Add an effect to the main model NAME=VALUE (repeatable; e.g. the one 'bmssim diagnose' found): "
                  "contact_resistance (ohm), hysteresis (V, half the gap between the OCV branches; starts on the "
                  "charge branch), current_offset (A, what the sensor reads at zero current), current_gain (relative). "
                  "Default: none (the paper's model)");
  sub->add_option("--points", c->o.mesh.n_neg, "--model full only: finite volumes per region")->capture_default_str();
  sub->add_option("--out", c->out, "Output folder (estimates.csv, summary.json)")->required();
  sub->add_flag("--quiet", c->quiet, "No progress lines");
  sub->add_option("--bound-noise-v-mv", c->bound_noise_v_mv,
                  "Scoring only (the estimator never reads it): summary.json's crlb, the Cramer-Rao bound of --settings "
                  "best's joint unknowns (initial film, growth gain, inventory) for white voltage noise of this standard "
                  "deviation [mV] over the ticks it learned in: the film per cycle, and growth_sd_pct, the bound on the "
                  "growth growth_err_pct scores relative to the true growth (its 1-sigma floor from the noise alone)");
  sub->add_flag("--write-firmware-stream", c->write_stream,
                "Also write firmware_stream.bin: the measurement stream the firmware ticked on (after the readers, the "
                "gaps and the model tick), for the board's replay of the same run (target/m4f_blind_main.cpp, BMSMEAS3)");
  sub->footer("Example: bmssim simulate --cycles 5 --out out/sim && bmssim estimate --data out/sim/truth.csv "
              "--model reduced --out out/est");
  return [c, sub]() { return run_estimate_command(*c, *sub); };
}

}  // namespace bms::app
