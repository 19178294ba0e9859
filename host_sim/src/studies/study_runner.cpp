#include "studies/study_runner.hpp"

#include <algorithm>
#include <cerrno>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <deque>
#include <fcntl.h>
#include <map>
#include <spawn.h>
#include <sys/wait.h>

#include <nlohmann/json.hpp>

#include "io/atomic_file.hpp"
#include "sim/truth_output.hpp"
#include "io/child_process.hpp"
#include "io/input_error.hpp"
#include "io/text_file.hpp"

extern char** environ;

namespace bms::study {

namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;

// posix_spawn rather than fork (the parent may hold large buffers, and spawn never copies
// them), in a process group of its own so an interrupt reaches the whole case.
pid_t spawn_logged(const fs::path& exe, const std::vector<std::string>& args, const fs::path& log) {
  std::vector<std::string> argv{exe.string()};
  argv.insert(argv.end(), args.begin(), args.end());
  SpawnOptions o;
  o.log = log;
  return spawn_process(argv, o);
}

double seconds_since(Clock::time_point t0) { return std::chrono::duration<double>(Clock::now() - t0).count(); }

}  // namespace

fs::path case_dir(const fs::path& out_dir, const std::string& name) { return out_dir / "cases" / name; }

std::vector<std::string> step_args(const fs::path& out_dir, const CaseSpec& c, const Step& s) {
  const std::string dir = case_dir(out_dir, c.name).string();
  std::vector<std::string> out;
  for (std::string a : s.args) {
    for (auto at = a.find("{case}"); at != std::string::npos; at = a.find("{case}", at + dir.size()))
      a.replace(at, 6, dir);
    out.push_back(a);
  }
  return out;
}

// A step's output is done when its summary.json exists and does not say "complete": false
// (a simulate that failed keeps its finished cycles under such a summary).
bool step_done(const fs::path& step_dir) {
  const fs::path file = step_dir / "summary.json";
  if (!fs::exists(file)) return false;
  const auto j = nlohmann::json::parse(read_text_file(file), nullptr, false);
  return j.is_object() && j.value("complete", true);
}

namespace {

// Adds the steps of `from` that `into` does not have (by name).
void merge_steps(CaseSpec& into, const CaseSpec& from) {
  for (const auto& s : from.steps) {
    const bool known = std::any_of(into.steps.begin(), into.steps.end(), [&](const Step& x) { return x.name == s.name; });
    if (!known) into.steps.push_back(s);
  }
}

}  // namespace

std::vector<CaseSpec> read_plan(const fs::path& out_dir) {
  const fs::path file = out_dir / "plan.json";
  std::vector<CaseSpec> cases;
  if (!fs::exists(file)) return cases;
  const auto j = nlohmann::json::parse(read_text_file(file), nullptr, false);
  if (!j.is_object() || !j.contains("cases") || !j["cases"].is_array())
    throw InputError(file.string() + ": not a study plan (no \"cases\" list)");
  for (const auto& c : j["cases"]) cases.push_back(case_from_json(c, file.string()));
  return cases;
}

void record_plan(const fs::path& out_dir, const std::vector<CaseSpec>& cases) {
  std::vector<CaseSpec> plan = read_plan(out_dir);
  for (const auto& c : cases) {
    const auto it = std::find_if(plan.begin(), plan.end(), [&](const CaseSpec& p) { return p.name == c.name; });
    if (it == plan.end()) plan.push_back(c);
    else merge_steps(*it, c);
  }
  nlohmann::json j = {{"cases", nlohmann::json::array()}};
  for (const auto& c : plan) j["cases"].push_back(case_json(c));
  fs::create_directories(out_dir);
  write_file_atomically(out_dir / "plan.json", j.dump(2) + "\n");
}

namespace {

}  // namespace

bool case_complete(const fs::path& out_dir, const CaseSpec& c) {
  for (const auto& s : c.steps)
    if (!step_done(case_dir(out_dir, c.name) / s.name)) return false;
  return true;
}

int run_case(const fs::path& exe, const fs::path& out_dir, const CaseSpec& c) {
  const fs::path dir = case_dir(out_dir, c.name);
  fs::create_directories(dir);
  // Runs with other --models or --arms may share the folder: case.json keeps every step
  // any run asked for, so --collect finds all of them.
  CaseSpec merged = c;
  if (fs::exists(dir / "case.json")) {
    merge_steps(merged, case_from_json(nlohmann::json::parse(read_text_file(dir / "case.json"), nullptr, false),
                                       (dir / "case.json").string()));
  }
  write_file_atomically(dir / "case.json", case_json(merged).dump(2) + "\n");
  nlohmann::json steps = nlohmann::json::array();
  int failed = 0;
  for (const auto& s : c.steps) {
    if (step_done(dir / s.name)) {
      steps.push_back({{"name", s.name}, {"status", "existing"}});
      continue;
    }
    const auto t0 = Clock::now();
    std::fprintf(stderr, "study: case %s: step %s\n", c.name.c_str(), s.name.c_str());
    std::fflush(stderr);
    const int rc = wait_process(spawn_logged(exe, step_args(out_dir, c, s), dir / "log.txt")).second;
    throw_if_interrupted();  // the step was stopped: no summary, so a re-run resumes it
    steps.push_back({{"name", s.name}, {"status", rc == 0 ? "done" : "failed"}, {"exit_code", rc},
                     {"wall_s", seconds_since(t0)}});
    if (rc != 0) {
      failed = rc;
      break;  // later steps read this step's output
    }
  }
  write_file_atomically(dir / "summary.json",
                        nlohmann::json{{"case", case_json(merged)}, {"complete", failed == 0}, {"steps", steps}}.dump(2) +
                            "\n");
  return failed;
}

int run_cases(const fs::path& exe, const fs::path& out_dir, const std::vector<CaseSpec>& cases, int jobs,
              const CaseArgs& case_args) {
  std::deque<const CaseSpec*> pending;
  for (const auto& c : cases) {
    if (case_complete(out_dir, c))
      std::fprintf(stderr, "study: case %s: complete, skipped\n", c.name.c_str());
    else
      pending.push_back(&c);
  }
  const std::size_t total = pending.size();
  std::size_t started = 0, finished = 0;
  int failures = 0;
  struct Running {
    const CaseSpec* spec;
    Clock::time_point t0;
  };
  std::map<pid_t, Running> running;
  const auto t_study = Clock::now();
  while (!pending.empty() || !running.empty()) {
    while (interrupt_signal() == 0 && !pending.empty() && static_cast<int>(running.size()) < jobs) {
      const CaseSpec* c = pending.front();
      pending.pop_front();
      const fs::path dir = case_dir(out_dir, c->name);
      fs::create_directories(dir);
      running[spawn_logged(exe, case_args(*c), dir / "log.txt")] = {c, Clock::now()};
      std::fprintf(stderr, "study: [%zu/%zu] started %s\n", ++started, total, c->name.c_str());
    }
    if (running.empty()) break;  // interrupted before the next start
    const auto [pid, rc] = wait_process(-1);
    const auto it = running.find(pid);
    if (it == running.end()) continue;
    ++finished;
    const fs::path log = case_dir(out_dir, it->second.spec->name) / "log.txt";
    if (rc == 0) {
      std::fprintf(stderr, "study: [%zu/%zu] done %s in %.0f s (%.0f s elapsed)\n", finished, total,
                   it->second.spec->name.c_str(), seconds_since(it->second.t0), seconds_since(t_study));
    } else {
      ++failures;
      std::fprintf(stderr, "study: [%zu/%zu] FAILED %s (exit %d), see %s\n", finished, total,
                   it->second.spec->name.c_str(), rc, log.c_str());
    }
    running.erase(it);
  }
  throw_if_interrupted();  // every child has ended (each got the signal)
  return failures;
}

}  // namespace bms::study
