#pragma once
// Runs study cases as child processes of bmssim itself (no threads in the solvers, so one
// process per core is the natural unit), with resume: a step whose summary.json exists is
// skipped, because every writer renames its summary.json into place only when done.
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "studies/study_plan.hpp"

namespace bms::study {

std::filesystem::path case_dir(const std::filesystem::path& out_dir, const std::string& name);
// The step's summary.json exists and does not say "complete": false.
bool step_done(const std::filesystem::path& step_dir);
// DIR/plan.json: every case and step a run or --list-cases planned, merged with the plan
// already there (runs with other --models or --arms may share DIR), so that --collect lists
// the steps of cases that never started as missing too. read_plan: empty without the file.
void record_plan(const std::filesystem::path& out_dir, const std::vector<CaseSpec>& cases);
std::vector<CaseSpec> read_plan(const std::filesystem::path& out_dir);
// Every step's summary.json exists.
bool case_complete(const std::filesystem::path& out_dir, const CaseSpec& c);
// The step's arguments with "{case}" replaced by the case folder.
std::vector<std::string> step_args(const std::filesystem::path& out_dir, const CaseSpec& c, const Step& s);

// Runs the case's missing steps one after another as children of `exe` (output appended to
// CASE/log.txt), then writes CASE/summary.json. Returns 0, or the first failing step's exit code.
int run_case(const std::filesystem::path& exe, const std::filesystem::path& out_dir, const CaseSpec& c);

// Runs `exe case_args(case)` for every incomplete case, at most `jobs` at once, with one
// progress line per start and end on stderr. Returns the number of failed cases.
using CaseArgs = std::function<std::vector<std::string>(const CaseSpec&)>;
int run_cases(const std::filesystem::path& exe, const std::filesystem::path& out_dir, const std::vector<CaseSpec>& cases,
              int jobs, const CaseArgs& case_args);

}  // namespace bms::study
