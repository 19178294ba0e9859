#pragma once
// The paper's sensitivity studies as a list of cases. A case is one truth simulation plus the
// estimator "arms" run on it; an arm is just a command line of bmssim and the name of the
// per-cycle field to read from its summary.json, so new estimators or baselines slot in here.
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

namespace bms::study {

struct StudyOptions {
  std::string mode = "all";  // noise | ic | all
  int seeds = 10;
  bool quick = false;
  std::vector<std::string> models = {"reduced", "full"};
  std::vector<std::string> arms;  // empty: every arm of the selected models and baselines
  bool baselines_available = false;  // `bmssim baseline` exists in this binary
};

// One child command of a case: `bmssim ARGS...` writing DIR/cases/CASE/NAME/summary.json.
struct Step {
  std::string name;               // "truth" or the arm name
  std::vector<std::string> args;  // after the program name; "{case}" is replaced by the case folder
  std::string metric;             // per-cycle field of summary.json (arms only)
};

struct CaseSpec {
  std::string name;
  std::string kind;  // ref | noise | current | truth_ic | model_ic
  int cycles = 5;
  double current_a = 2.5;
  double noise_v_mv = 0.0, noise_i_ma = 0.0;
  unsigned seed = 1;
  double truth_ic_pct = 0.0, model_ic_pct = 0.0;
  std::vector<Step> steps;  // steps[0] is the truth simulation
};

// Cycles per case: 5 (the paper), 2 with --quick.
int study_cycles(const StudyOptions& o);
// Noise levels of the paper: output 0.02 / 0.2 mV, input 0.5 / 5 mA.
struct NoiseLevel {
  std::string name;
  double noise_v_mv, noise_i_ma;
};
const std::vector<NoiseLevel>& noise_levels();

// Throws InputError naming the option for an unknown mode, model or arm.
std::vector<CaseSpec> plan_cases(const StudyOptions& o);

nlohmann::json case_json(const CaseSpec& c);
// Reads back the fields written by case_json (not the steps); InputError naming FILE.
CaseSpec case_from_json(const nlohmann::json& j, const std::string& file);

}  // namespace bms::study
