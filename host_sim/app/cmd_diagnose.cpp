// bmssim diagnose: residual of the truth model against measured data, candidate effects
// fitted and scored on held-out data, before/after report (contract: diagnose).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <sstream>
#include <string>
#include <vector>

#include <fmt/format.h>

#include "commands.hpp"
#include "simulate_options.hpp"
#include "diagnosis/diagnose.hpp"
#include "diagnosis/report.hpp"
#include "io/child_process.hpp"
#include "io/input_error.hpp"
#include "io/output_folder.hpp"
#include "io/measured_profile.hpp"
#include "sim/cell_catalog.hpp"

namespace bms::app {

namespace {

// Below this (A) a whole record is at rest: no effect shows in the voltage.
constexpr double kRestCurrentA = 1e-3;

struct DiagnoseOptions {
  std::vector<std::string> data;
  std::string cell;
  std::string out;
  std::string candidates = "all";
  int points = 20, radial = 20, search_points = 8, search_radial = 8;
  double rtol = 1e-6;
  int blocks = 8;
  int max_effects = 3;
  double search_drive_tolerance = 0.0;
  double open_gain = 0.1;
  int threads = 0;
  std::string initial_soc = "auto";
  std::string current_sign = "by-layout";
  bool quiet = false;
};

std::vector<diagnosis::Effect> parse_candidates(const std::string& list) {
  using diagnosis::Effect;
  if (list == "all") return {std::begin(diagnosis::kAllCandidates), std::end(diagnosis::kAllCandidates)};
  if (list == "listed") return {std::begin(diagnosis::kListedCandidates), std::end(diagnosis::kListedCandidates)};
  std::vector<Effect> out;
  std::stringstream ss(list);
  std::string name;
  while (std::getline(ss, name, ',')) {
    if (name == "all" || name == "listed") {
      for (Effect k : parse_candidates(name))
        if (std::find(out.begin(), out.end(), k) == out.end()) out.push_back(k);
      continue;
    }
    Effect e = Effect::none;
    if (!diagnosis::parse_effect(name, e) || e == Effect::none) {
      std::string known;
      for (Effect k : diagnosis::kAllCandidates) known += std::string(known.empty() ? "" : ", ") + diagnosis::effect_name(k);
      throw InputError("--candidates: unknown effect '" + name + "'; use all, listed or a comma-separated list of " +
                       known + ", particle_size");
    }
    out.push_back(e);
  }
  if (out.empty()) throw InputError("--candidates: empty list");
  return out;
}

std::string command_line(const DiagnoseOptions& o) {
  std::string s = "bmssim diagnose";
  for (const auto& d : o.data) s += " --data " + d;
  s += " --cell " + o.cell;
  if (o.candidates != "all") s += " --candidates " + o.candidates;
  if (o.points != 20 || o.radial != 20) s += fmt::format(" --points {} --radial {}", o.points, o.radial);
  if (o.search_points != 8 || o.search_radial != 8)
    s += fmt::format(" --search-points {} --search-radial {}", o.search_points, o.search_radial);
  if (o.rtol != 1e-6) s += fmt::format(" --rtol {}", o.rtol);
  if (o.blocks != 8) s += fmt::format(" --blocks {}", o.blocks);
  if (o.max_effects != 3) s += fmt::format(" --max-effects {}", o.max_effects);
  if (o.open_gain != 0.1) s += fmt::format(" --open-gain {}", o.open_gain);
  if (o.search_drive_tolerance > 0) s += fmt::format(" --search-drive-tolerance {}", o.search_drive_tolerance);
  if (o.threads != 0) s += fmt::format(" --threads {}", o.threads);
  if (o.initial_soc != "auto") s += " --initial-soc " + o.initial_soc;
  if (o.current_sign != "by-layout") s += " --current-sign " + o.current_sign;
  return s + " --out " + o.out;
}

int run_diagnose(const DiagnoseOptions& o) {
  if (!(o.rtol > 0.0 && o.rtol < 1e-2)) throw InputError("--rtol: must be in (0, 0.01)");
  diagnosis::DiagnoseSettings settings;
  settings.candidates = parse_candidates(o.candidates);
  settings.final_mesh = {o.points, o.points, o.points, o.radial};
  settings.search_mesh = {o.search_points, o.search_points, o.search_points, o.search_radial};
  settings.rtol = o.rtol;
  settings.blocks = o.blocks;
  settings.max_effects = o.max_effects;
  settings.search_drive_tolerance = o.search_drive_tolerance;
  settings.open_gain = o.open_gain;
  settings.threads = o.threads;
  const CurrentSign sign = current_sign_option(o.current_sign);
  const CellParameters cell = load_cell(o.cell);
  std::vector<diagnosis::Record> records;
  for (const auto& d : o.data) {
    records.push_back(diagnosis::load_record(d, sign));
    check_record_currents(d, records.back().t_s, records.back().current_a, cell);
    double imax = 0.0;
    for (double i : records.back().current_a) imax = std::max(imax, std::abs(i));
    if (!(imax > kRestCurrentA))
      throw InputError(fmt::format("{}: no current flows in the record (|I| <= {} A throughout): there is nothing to "
                                   "diagnose; give a record with current steps",
                                   d, kRestCurrentA));
    diagnosis::set_initial_state(records.back(), cell, o.initial_soc);
  }
  // Checked before the long work; every file is written under DIR.partial-PID, which replaces
  // DIR only once the report, its plots and summary.json are all written (io/output_folder.hpp).
  OutputFolder folder(o.out);
  auto log = [q = o.quiet](const std::string& s) {
    if (!q) std::fprintf(stderr, "diagnose: %s\n", s.c_str());
  };
  const auto result = diagnosis::diagnose(cell, records, settings, log);
  if (!result.excitation_note.empty())
    std::fprintf(stderr, "diagnose: note: %s\n", result.excitation_note.c_str());
  const diagnosis::ReportContext ctx{command_line(o), o.cell, settings};
  const auto plots = diagnosis::write_report(folder.staging(), result, ctx);
  throw_if_interrupted();
  folder.commit();
  if (plots.empty()) std::fprintf(stderr, "diagnose: warning: no plots (see %s/report.md)\n", o.out.c_str());
  std::fprintf(stderr, "diagnose: %s: held-out RMSE %.3f -> %.3f mV, all %.3f -> %.3f mV (%s) -> %s\n",
               diagnosis::effect_name(result.answer), result.heldout_before_mv,
               result.explained ? result.heldout_after_mv : result.heldout_before_mv, result.rmse_before_mv,
               result.explained ? result.rmse_after_mv : result.rmse_before_mv, result.reason.c_str(),
               o.out.c_str());
  return 0;
}

}  // namespace

Runner add_diagnose(CLI::App& app) {
  auto* sub = app.add_subcommand(
      "diagnose",
      "Run the truth model on measured current, characterise the voltage residual, fit candidate effects and "
      "parameter re-fits on part of the data, score them on the rest, select up to three, and answer with the "
      "effects that explain the residual, none (at the noise floor) or unexplained (with where the residual lives)");
  auto o = std::make_shared<DiagnoseOptions>();
  sub->add_option("--data", o->data,
                  "Measured record: About:Energy 'Time [s],I[A],U[V]', truth.csv (its current_meas_a and "
                  "voltage_meas_v; temperature_k when present), or any CSV with time, current and voltage columns "
                  "(picked by name). Repeatable: each record is scored with the parameters fitted on the others")
      ->required();
  sub->add_option("--cell", o->cell, "paper | aboutenergy | lco | nmc | FILE.bpx.json")->required();
  sub->add_option("--out", o->out, "Output folder (summary.json, report.md, residual.csv, PNG plots)")->required();
  sub->add_option("--candidates", o->candidates,
                  "all (the five listed effects, voltage_offset, voltage_gain, rc_branch, time_skew and the "
                  "parameter re-fits diffusivity_positive/negative, conductivity, electrolyte_diffusivity, "
                  "i0_positive/negative, initial_soc), listed (contact_resistance, hysteresis, current_offset, "
                  "current_gain, thermal), or a comma-separated list (particle_size only when listed)")
      ->capture_default_str();
  sub->add_option("--max-effects", o->max_effects, "Forward selection: at most this many effects combined")
      ->capture_default_str()->check(CLI::Range(1, 3));
  sub->add_option("--open-gain", o->open_gain,
                  "A first effect too weak to be named alone opens a combination when it cuts the held-out RMSE by "
                  "this share (0: always explore combinations from the best single effect)")
      ->capture_default_str()->check(CLI::Range(0.0, 1.0));
  sub->add_option("--initial-soc", o->initial_soc,
                  "auto (from the first rest voltage when the record does not start in the cell's default state), "
                  "full (the default state) or a state of charge in [0, 1]")
      ->capture_default_str();
  sub->add_option("--current-sign", o->current_sign,
                  "discharge-positive | charge-positive (default: by the file's layout: truth.csv discharge-positive, "
                  "other cycler files charge-positive)")
      ->capture_default_str();
  sub->add_option("--points", o->points, "Final mesh: finite volumes per region")->capture_default_str()->check(CLI::Range(2, 400));
  sub->add_option("--radial", o->radial, "Final mesh: finite volumes per particle")->capture_default_str()->check(CLI::Range(3, 400));
  sub->add_option("--search-points", o->search_points, "Search mesh (every fit evaluation is a full run)")
      ->capture_default_str()->check(CLI::Range(2, 400));
  sub->add_option("--search-radial", o->search_radial, "Search mesh: finite volumes per particle")
      ->capture_default_str()->check(CLI::Range(3, 400));
  sub->add_option("--rtol", o->rtol, "IDA relative tolerance")->capture_default_str();
  sub->add_option("--search-drive-tolerance", o->search_drive_tolerance,
                  "Search runs follow the measured current as straight pieces within this share of its largest "
                  "value (e.g. 0.02 for a drive cycle: far fewer solver stops; the final runs use the exact current)")
      ->capture_default_str()->check(CLI::Range(0.0, 0.2));
  sub->add_option("--blocks", o->blocks, "One record: split into this many blocks, alternately training and validation")
      ->capture_default_str()->check(CLI::Range(2, 1000));
  sub->add_option("--threads", o->threads,
                  "Candidates and sensitivities on this many threads (0: one per core); the answer and every number "
                  "are the same for any count")
      ->capture_default_str()->check(CLI::Range(0, 64));
  sub->add_flag("--quiet", o->quiet, "No progress output");
  sub->footer(
      "Exit codes: 0 diagnosis written (possibly 'none', with the reason), 1 runtime failure, 2 bad input.\n"
      "Example: bmssim simulate --cell paper --protocol cccv --effect contact_resistance=0.001 --out out/rc\n"
      "         bmssim diagnose --data out/rc/truth.csv --cell paper --out out/rc-diag");
  return [o]() { return run_diagnose(*o); };
}

}  // namespace bms::app
