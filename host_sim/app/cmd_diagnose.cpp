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
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "simulate_options.hpp"
#include "diagnosis/augmented_cell.hpp"
#include "diagnosis/diagnose.hpp"
#include "diagnosis/report.hpp"
#include "io/atomic_file.hpp"
#include "io/bpx_writer.hpp"
#include "io/child_process.hpp"
#include "io/input_error.hpp"
#include "io/output_folder.hpp"
#include "io/measured_profile.hpp"
#include "io/text_file.hpp"
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
  int beam = 2;
  int threads = 0;
  std::string initial_soc = "auto";
  std::string current_sign = "by-layout";
  std::string write_cell;
  bool write_cell_partial = false;
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
  if (o.beam != 2) s += fmt::format(" --beam {}", o.beam);
  if (o.search_drive_tolerance > 0) s += fmt::format(" --search-drive-tolerance {}", o.search_drive_tolerance);
  if (o.threads != 0) s += fmt::format(" --threads {}", o.threads);
  if (o.initial_soc != "auto") s += " --initial-soc " + o.initial_soc;
  if (o.current_sign != "by-layout") s += " --current-sign " + o.current_sign;
  if (!o.write_cell.empty()) s += " --write-cell " + o.write_cell;
  if (o.write_cell_partial) s += " --write-cell-partial";
  return s + " --out " + o.out;
}

// --write-cell: the input cell's BPX JSON (the built-in paper cell has none) and where it came from.
nlohmann::json input_cell_json(const std::string& cell, std::string& source) {
  std::filesystem::path file;
  if (cell == "paper")
    throw InputError("--write-cell: the built-in paper cell has no BPX file to write an augmented cell from; give "
                     "--cell aboutenergy, lco, nmc or a FILE.bpx.json");
  if (cell == "aboutenergy") file = shared_dir() / "data/aboutenergy-lfp18650/lfp_18650_cell_BPX.json";
  else if (cell == "lco" || cell == "nmc") file = cell_template_file(cell);
  else file = cell;
  source = file.string();
  try {
    return nlohmann::json::parse(read_text_file(file));
  } catch (const nlohmann::json::exception& e) {
    throw InputError("--cell " + source + ": not JSON (" + e.what() + ")");
  }
}

// What --write-cell writes: the knobs of the answer (explained), or with --write-cell-partial the
// best partial model (unexplained) or nothing added (none). The cell is not written when the
// answer is not `explained` and the option does not ask for it, or when a knob is no property of
// the cell (`refused`, one line naming it).
struct CellPlan {
  bool write = false;
  std::string refused;
  diagnosis::AugmentedCell cell;
  nlohmann::json summary;
};

CellPlan plan_cell(const DiagnoseOptions& o, const diagnosis::DiagnosisResult& r, const nlohmann::json& input,
                   const CellParameters& input_cell, const std::string& source) {
  CellPlan p;
  const bool use = r.explained || o.write_cell_partial;
  const diagnosis::Hypothesis& h = r.explained ? r.model : r.best_partial;
  const std::string answer = diagnosis::effect_name(r.answer);
  std::string note;
  if (!use) {
    note = fmt::format("no cell written: the answer is `{}` (not explained); --write-cell-partial writes the best "
                       "combination reached anyway",
                       answer);
  } else {
    p.cell = diagnosis::augment_cell(input, input_cell, h);
    if (!p.cell.refused.empty()) {
      p.refused = p.cell.refused;
      note = "no cell written: " + p.refused;
    } else {
      p.write = true;
      note = fmt::format("{}/cell.bpx.json: the cell '{}' ({}) with {} ({}; fitted on all the data). Answer `{}`{}.",
                         o.write_cell, o.cell, source,
                         p.cell.added.empty() ? std::string("nothing added") : fmt::format("{}", fmt::join(p.cell.added, "; ")),
                         r.explained ? "the explaining effects" : "the best partial combination, not an explanation",
                         answer,
                         r.explained ? fmt::format(": held-out RMSE {:.3f} -> {:.3f} mV", r.heldout_before_mv,
                                                   r.heldout_after_mv)
                                     : fmt::format(" (best reached {:.3f} mV of {:.3f} mV held out)",
                                                   r.best_partial_heldout_mv, r.heldout_before_mv));
    }
  }
  p.summary = {{"dir", o.write_cell},
               {"written", p.write},
               {"from", r.explained ? "answer" : (use ? "best_partial" : "none")},
               {"effects", p.cell.added_json},
               {"note", note}};
  if (!p.refused.empty()) p.summary["refused"] = p.refused;
  return p;
}

void write_cell_file(const std::filesystem::path& dir, const DiagnoseOptions& o, const CellPlan& p,
                     const nlohmann::json& input) {
  write_bpx_cell(dir / "cell.bpx.json", p.cell.bpx, fmt::format("Augmented by bmssim diagnose from cell '{}'", o.cell),
                 fmt::format("{} Made by `{}`; every other value is the input cell's. Input description: {}",
                             p.summary.value("note", std::string()), command_line(o),
                             input.value("/Header/Description"_json_pointer, std::string("(none)"))));
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
  settings.beam = o.beam;
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
  if (o.write_cell_partial && o.write_cell.empty()) throw InputError("--write-cell-partial: only with --write-cell DIR");
  std::string cell_source;
  const nlohmann::json cell_json = o.write_cell.empty() ? nlohmann::json() : input_cell_json(o.cell, cell_source);
  // Checked before the long work; every file is written under DIR.partial-PID, which replaces
  // DIR only once the report, its plots and summary.json are all written (io/output_folder.hpp).
  OutputFolder folder(o.out);
  // --write-cell DIR: its own output folder (cell.bpx.json, summary.json), or the --out folder itself.
  const bool cell_in_out = !o.write_cell.empty() && std::filesystem::weakly_canonical(o.write_cell) ==
                                                        std::filesystem::weakly_canonical(o.out);
  std::unique_ptr<OutputFolder> cell_folder;
  if (!o.write_cell.empty() && !cell_in_out) cell_folder = std::make_unique<OutputFolder>(o.write_cell, "--write-cell");
  auto log = [q = o.quiet](const std::string& s) {
    if (!q) std::fprintf(stderr, "diagnose: %s\n", s.c_str());
  };
  const auto result = diagnosis::diagnose(cell, records, settings, log);
  if (!result.excitation_note.empty())
    std::fprintf(stderr, "diagnose: note: %s\n", result.excitation_note.c_str());
  diagnosis::ReportContext ctx{command_line(o), o.cell, settings};
  CellPlan cell_plan;
  if (!o.write_cell.empty()) {
    cell_plan = plan_cell(o, result, cell_json, cell, cell_source);
    ctx.extra["write_cell"] = cell_plan.summary;
  }
  const auto plots = diagnosis::write_report(folder.staging(), result, ctx);
  throw_if_interrupted();
  // The cell first: a cell that cannot be written leaves no diagnosis that says it was.
  if (cell_plan.write) {
    write_cell_file(cell_in_out ? folder.staging() : cell_folder->staging(), o, cell_plan, cell_json);
    if (cell_folder) {
      AtomicFileWriter w(cell_folder->staging() / "summary.json");
      w.append(nlohmann::json({{"command", command_line(o)}, {"diagnosis", o.out}, {"write_cell", cell_plan.summary}})
                   .dump(2) +
               "\n");
      w.commit();
      cell_folder->commit();
    }
  }
  folder.commit();
  if (plots.empty()) std::fprintf(stderr, "diagnose: warning: no plots (see %s/report.md)\n", o.out.c_str());
  std::fprintf(stderr, "diagnose: %s: held-out RMSE %.3f -> %.3f mV, all %.3f -> %.3f mV (%s) -> %s\n",
               diagnosis::effect_name(result.answer), result.heldout_before_mv,
               result.explained ? result.heldout_after_mv : result.heldout_before_mv, result.rmse_before_mv,
               result.explained ? result.rmse_after_mv : result.rmse_before_mv, result.reason.c_str(),
               o.out.c_str());
  if (!o.write_cell.empty()) {
    std::fprintf(stderr, "diagnose: --write-cell: %s\n", cell_plan.summary.value("note", std::string()).c_str());
    if (!cell_plan.refused.empty()) return 1;
  }
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
                  "voltage_meas_v; temperature_k when present), a cycler's export (Arbin, Maccor, Neware, BioLogic "
                  ".mpt, NASA PCoE), or any CSV with time, current and voltage columns (picked by name). Repeatable: each record is scored with the parameters fitted on the others")
      ->required();
  sub->add_option("--cell", o->cell, "paper | aboutenergy | lco | nmc | FILE.bpx.json")->required();
  sub->add_option("--out", o->out, "Output folder (summary.json, report.md, residual.csv, PNG plots)")->required();
  sub->add_option("--candidates", o->candidates,
                  "all (the five listed effects, voltage_offset, voltage_gain, rc_branch, time_skew and the "
                  "parameter re-fits diffusivity_positive/negative, conductivity, electrolyte_diffusivity, "
                  "i0_positive/negative, initial_soc, and diffusivity_profile_positive: a cathode solid diffusivity "
                  "that falls log-linearly in stoichiometry from a knee to full lithiation, two knobs, the factor "
                  "at x = 1 and the knee, and resistive_reactant_positive: a cathode reaction resistance that grows "
                  "log-linearly with the particles' mean stoichiometry from a knee, three knobs), listed "
                  "(contact_resistance, hysteresis, current_offset, "
                  "current_gain, thermal), or a comma-separated list (particle_size only when listed)")
      ->capture_default_str();
  sub->add_option("--max-effects", o->max_effects, "Forward selection: at most this many effects combined")
      ->capture_default_str()->check(CLI::Range(1, 3));
  sub->add_option("--open-gain", o->open_gain,
                  "A first effect too weak to be named alone opens a combination when it cuts the held-out RMSE by "
                  "this share (0: always explore combinations from the best single effect)")
      ->capture_default_str()->check(CLI::Range(0.0, 1.0));
  sub->add_option("--beam", o->beam,
                  "Such combinations are grown from this many of the best single effects (each path greedy; another "
                  "start's path is taken only when it cuts the held-out RMSE by the complexity penalty)")
      ->capture_default_str()->check(CLI::Range(1, 5));
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
  sub->add_option("--write-cell", o->write_cell,
                  "Also write DIR/cell.bpx.json: the --cell's BPX file with the effects the answer names, at their "
                  "sizes fitted on all the data (re-fits scale the BPX fields; contact_resistance, hysteresis, thermal, "
                  "particle_size, diffusivity_profile_positive and resistive_reactant_positive go into User-defined keys the BPX "
                  "reader reads), for any --cell. Written only "
                  "when the answer is explained, unless --write-cell-partial. A sensor error, time skew, RC branch or "
                  "start state is not a property of the cell: then no cell is written and the exit code is 1. DIR may "
                  "be the --out folder; else it gets its own summary.json. Not with --cell paper (no BPX file)");
  sub->add_flag("--write-cell-partial", o->write_cell_partial,
                "With --write-cell: write the cell also when the answer is unexplained (the best combination reached, "
                "best_partial in summary.json: not an explanation) or none (nothing added)");
  sub->add_flag("--quiet", o->quiet, "No progress output");
  sub->footer(
      "Exit codes: 0 diagnosis written (possibly 'none', with the reason), 1 runtime failure, 2 bad input.\n"
      "Example: bmssim simulate --cell paper --protocol cccv --effect contact_resistance=0.001 --out out/rc\n"
      "         bmssim diagnose --data out/rc/truth.csv --cell paper --out out/rc-diag");
  return [o]() { return run_diagnose(*o); };
}

}  // namespace bms::app
