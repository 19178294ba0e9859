// bmssim study: the paper's sensitivity studies (noise, initial conditions) as parallel cases.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <unistd.h>

#include <fmt/format.h>

#include "commands.hpp"
#include "studies/study_blind.hpp"
#include "io/input_error.hpp"
#include "io/shell_word.hpp"
#include "sim/truth_output.hpp"
#include "studies/study_collect.hpp"
#include "studies/study_plan.hpp"
#include "studies/study_report.hpp"
#include "studies/study_runner.hpp"

namespace bms::app {

namespace {

namespace fs = std::filesystem;

struct StudyCli {
  study::StudyOptions o;
  std::string out, collect_dir, one_case;
  int jobs = 0;
  bool list_cases = false;
  std::string blind_sets = "1,2";
  int blind_cycles = 5;
  std::string cell = "paper";  // blind only
  int truth_points = 20;       // blind only: the truth DFN's volumes per region and per particle
  double truth_rtol = 1e-6;    // blind only: its solver tolerance
};

std::string join(const std::vector<std::string>& v, const char* sep) {
  std::string s;
  for (const auto& x : v) s += (s.empty() ? "" : sep) + x;
  return s;
}

// Arguments after the program name that make a child run exactly one case of the same plan.
std::vector<std::string> case_argv(const StudyCli& c, const std::string& out_abs, const std::string& name) {
  std::vector<std::string> a = {"study", c.o.mode, "--out", out_abs, "--case", name, "--seeds", std::to_string(c.o.seeds),
                                "--models", join(c.o.models, ",")};
  if (c.o.quick) a.push_back("--quick");
  if (!c.o.arms.empty()) a.insert(a.end(), {"--arms", join(c.o.arms, ",")});
  return a;
}

int collect_and_report(const fs::path& dir, const nlohmann::json& options, const std::string& command) {
  std::fprintf(stderr, "study: collecting %s\n", dir.c_str());
  study::Collected col = study::collect(dir);
  col.summary["options"] = options;
  col.summary["command"] = command;
  const int drawn = study::draw_figures(dir, col);
  col.summary["figures_drawn"] = drawn;
  study::write_report(dir, col, drawn, command);
  write_file_atomically(dir / "summary.json", col.summary.dump(2) + "\n");
  std::fprintf(stderr, "study: %d figures, %zu missing steps -> %s, %s\n", drawn, col.missing.size(),
               (dir / "summary.json").c_str(), (dir / "report.md").c_str());
  return 0;
}

int run_blind(const StudyCli& c, const CLI::App& sub) {
  study::BlindStudyOptions b;
  b.seeds = sub.count("--seeds") ? c.o.seeds : (c.o.quick ? 2 : 10);
  b.cycles = c.o.quick && sub.count("--cycles") == 0 ? 3 : c.blind_cycles;
  b.sets = c.o.quick && sub.count("--sets") == 0 ? "1" : c.blind_sets;
  b.jobs = c.jobs > 0 ? c.jobs : static_cast<int>(std::max(1L, sysconf(_SC_NPROCESSORS_ONLN)));
  b.out = c.out;
  b.arms = c.o.arms;
  b.list_cases = c.list_cases;
  b.cell = c.cell;
  b.truth_points = c.truth_points;
  b.truth_rtol = c.truth_rtol;
  const bool default_mesh = sub.count("--truth-points") == 0 && sub.count("--truth-rtol") == 0;
  const std::string command =
      fmt::format("bmssim study blind{} --seeds {} --cycles {} --sets {}{}{} --out {}",
                  c.cell == "paper" ? std::string() : " --cell " + c.cell, b.seeds, b.cycles, b.sets,
                  b.arms.empty() ? std::string() : " --arms " + join(b.arms, ","),
                  default_mesh ? std::string() : fmt::format(" --truth-points {} --truth-rtol {}", b.truth_points, b.truth_rtol),
                  c.out);
  const int failed = study::run_blind_study(b, command);
  if (failed > 0) std::fprintf(stderr, "study blind: %d truth(s) could not be simulated (summary.json: truth_failures)\n", failed);
  return failed > 0 ? 1 : 0;
}

// --quick's smaller plan, and the full plan's seeds, where the options were not given.
void apply_plan_defaults(StudyCli& c, const CLI::App& sub, CLI::App& root) {
  if (c.o.quick) {
    if (sub.count("--seeds") == 0) c.o.seeds = 2;
    if (sub.count("--models") == 0) c.o.models = {"reduced"};
    if (sub.count("--arms") == 0)
      for (const auto& m : c.o.models) c.o.arms.insert(c.o.arms.end(), {m + "-paper", m + "-best"});
    if (sub.count("--arms") == 0 && std::count(c.o.models.begin(), c.o.models.end(), "reduced"))
      c.o.arms.push_back("reduced-beyond");
  } else if (sub.count("--seeds") == 0) {
    c.o.seeds = 10;
  }
  try {
    c.o.baselines_available = root.get_subcommand("baseline") != nullptr;
  } catch (const CLI::OptionNotFound&) {
    c.o.baselines_available = false;
  }
}

void print_case_commands(const StudyCli& c, const std::vector<study::CaseSpec>& cases, const fs::path& exe,
                         const fs::path& out) {
  for (const auto& cs : cases) {
    std::string line = shell_word(exe.string());
    for (const auto& a : case_argv(c, out.string(), cs.name)) line += " " + shell_word(a);
    std::printf("%s\n", line.c_str());
  }
  std::fprintf(stderr, "study: %zu cases; afterwards: %s study %s --collect %s\n", cases.size(),
               shell_word(exe.string()).c_str(), c.o.mode.c_str(), shell_word(out.string()).c_str());
}

int run_all_cases(const StudyCli& c, const std::vector<study::CaseSpec>& cases, const fs::path& self,
                  const fs::path& out) {
  const long cores = sysconf(_SC_NPROCESSORS_ONLN);
  const int jobs = c.jobs > 0 ? c.jobs : static_cast<int>(std::max(1L, cores));
  fs::create_directories(out);
  study::record_plan(out, cases);  // for --collect: what was planned, run or not
  std::fprintf(stderr, "study: %zu cases, %d at once -> %s\n", cases.size(), jobs, out.c_str());
  const int failed = study::run_cases(self, out, cases, jobs, [&](const study::CaseSpec& cs) {
    return case_argv(c, out.string(), cs.name);
  });
  std::string command = "bmssim study " + c.o.mode + fmt::format(" --seeds {}", c.o.seeds) +
                        (c.o.quick ? " --quick" : "") + " --models " + join(c.o.models, ",") +
                        (c.o.arms.empty() ? "" : " --arms " + join(c.o.arms, ",")) + " --out " + c.out;
  const nlohmann::json options = {{"mode", c.o.mode},   {"seeds", c.o.seeds}, {"quick", c.o.quick},
                                  {"models", c.o.models}, {"arms", c.o.arms},   {"jobs", jobs},
                                  {"cases", cases.size()}, {"failed_cases", failed}};
  collect_and_report(out, options, command);
  if (failed > 0) {
    std::fprintf(stderr, "study: %d case(s) failed (see cases/<case>/log.txt); summary has what completed\n", failed);
    return 1;
  }
  return 0;
}

int run_study(StudyCli& c, const CLI::App& sub, CLI::App& root) {
  if (!c.collect_dir.empty()) {
    const fs::path dir = fs::absolute(c.collect_dir);
    if (!fs::is_directory(dir)) throw InputError("--collect: " + dir.string() + " is not a folder");
    return collect_and_report(dir, {{"collected_only", true}}, "bmssim study " + c.o.mode + " --collect " + c.collect_dir);
  }
  if (c.o.mode == "blind") return run_blind(c, sub);
  if (sub.count("--cell") > 0) throw InputError("--cell: only `study blind` runs on another cell (the paper's studies are the paper cell's)");
  if (c.out.empty()) throw InputError("--out: required (or --collect DIR)");
  apply_plan_defaults(c, sub, root);
  const std::vector<study::CaseSpec> cases = study::plan_cases(c.o);
  // Children run /proc/self/exe: the same image even if the file is rebuilt during a long study.
  const fs::path self = "/proc/self/exe";
  const fs::path exe = fs::read_symlink(self);
  const fs::path out = fs::absolute(c.out);
  if (c.list_cases) {
    study::record_plan(out, cases);  // for --collect: what was planned, run or not
    print_case_commands(c, cases, exe, out);
    return 0;
  }
  if (!c.one_case.empty()) {
    const auto it = std::find_if(cases.begin(), cases.end(), [&](const auto& cs) { return cs.name == c.one_case; });
    if (it == cases.end()) throw InputError("--case: no case '" + c.one_case + "' in this plan (see --list-cases)");
    return study::run_case(self, out, *it) == 0 ? 0 : 1;
  }
  return run_all_cases(c, cases, self, out);
}

}  // namespace

Runner add_study(CLI::App& app) {
  auto* sub = app.add_subcommand(
      "study",
      "The paper's sensitivity studies: measurement noise (figures 8-13) and initial-condition errors "
      "(figures 14-17), each case a truth simulation plus the estimator arms, run in parallel");
  auto c = std::make_shared<StudyCli>();
  sub->add_option("mode", c->o.mode,
                  "noise | ic | all (the paper's studies) | blind (truths the estimator does not know: "
                  "docs/results/blind.md)")
      ->required()
      ->check(CLI::IsMember({"noise", "ic", "all", "blind"}));
  sub->add_option("--sets", c->blind_sets,
                  "blind: truth sets, comma-separated: 1 (film, growth law, side i0, inventory), 2 (and conductivity, "
                  "solid diffusivities), 3 (set 1 at 5-45 C, every third truth self-heating), 4 (set 1 and "
                  "cell-to-cell spread: transport, kinetics, particle sizes, capacity), 5 (set 1 measured by a BMS "
                  "front end: both noises, current offset and gain, voltage offset, temperature sensor 0.5 K off), "
                  "6 (set 1 under a protocol drawn per truth: partial charges at 0.3-1C, rests)")
      ->capture_default_str();
  sub->add_option("--cycles", c->blind_cycles, "blind: CCCV cycles per truth")->capture_default_str();
  sub->add_option("--cell", c->cell,
                  "blind: the cell the truths are drawn around and the firmware's reduced model is built from: paper | "
                  "aboutenergy | lco | nmc | FILE.bpx.json. Another cell than the paper's cycles at its 1C to its "
                  "voltage limits with a C/20 CV end, the best arms use its design-time bias (computed once), the "
                  "EKF and batch baselines (paper cell only) are left out, and the bound is given for voltage noise alone")
      ->capture_default_str();
  sub->add_option("--truth-points", c->truth_points,
                  "blind: finite volumes per region and per particle of every truth's DFN (simulate --points N:N). "
                  "A coarse truth carries its own mesh error, which the estimator reads as film (on About:Energy "
                  "about 1 % of the film at 20 against 80: docs/results/firmware-model.md)")
      ->check(CLI::Range(10, 200))
      ->capture_default_str();
  sub->add_option("--truth-rtol", c->truth_rtol, "blind: every truth's IDA relative tolerance (simulate --rtol)")
      ->check(CLI::Range(1e-10, 1e-4))
      ->capture_default_str();
  sub->add_option("--seeds", c->o.seeds, "Noise seeds per noise level (default 10; 2 with --quick)")
      ->check(CLI::Range(1, 10000));
  sub->add_flag("--quick", c->o.quick,
                "Short form for CI: 2 cycles instead of 5, 2 seeds, reduced model only, no baselines "
                "(unless --seeds/--models/--arms say otherwise)");
  sub->add_option("--jobs", c->jobs, "Cases run at once (default: the number of cores)")->check(CLI::Range(1, 1024));
  sub->add_option("--models", c->o.models, "Main models of the estimator arms, comma-separated: reduced, full "
                  "(default both; the full model takes about 4 min per 5-cycle arm)")
      ->delimiter(',');
  sub->add_option("--arms", c->o.arms, "Only these arms, comma-separated: reduced-paper, reduced-best, reduced-beyond, "
                  "full-paper, full-best, ekf, batch, crlb (default: all arms of --models, and the baselines when "
                  "'bmssim baseline' exists); blind: best, best-no-learning, ... (docs/results/blind.md), ekf, batch")
      ->delimiter(',');
  sub->add_option("--out", c->out, "Output folder: cases/<case>/, figures/, summary.json, report.md");
  sub->add_flag("--list-cases", c->list_cases,
                "Print one self-contained command line per case (for GNU parallel or a job array) and exit; "
                "then merge with --collect (blind: each case's name and the simulate line of its truth)");
  sub->add_option("--collect", c->collect_dir,
                  "Merge the case outputs already in DIR into summary.json, figures and report.md; runs nothing");
  sub->add_option("--case", c->one_case, "Run only this case (what --list-cases prints)");
  sub->footer(
      "Cases already complete in --out are skipped, so a re-run resumes. Examples:\n"
      "  bmssim study all --out out/study                      # everything, all cores\n"
      "  bmssim study noise --quick --out out/study-quick      # a few minutes\n"
      "  bmssim study all --out out/s --list-cases | parallel -j 8 && bmssim study all --collect out/s");
  CLI::App* root = &app;
  return [c, sub, root]() { return run_study(*c, *sub, *root); };
}

}  // namespace bms::app
