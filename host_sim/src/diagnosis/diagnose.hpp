#pragma once
// The diagnosis: run the plain model on the measured records, fit every candidate effect on
// the training part, score it on the held-out part, choose one or `none`, and re-run with it.
#include <functional>
#include <string>
#include <vector>

#include "diagnosis/characterise.hpp"
#include "diagnosis/model_run.hpp"
#include "diagnosis/records.hpp"
#include "diagnosis/selection.hpp"

namespace bms::diagnosis {

struct DiagnoseSettings {
  DfnMesh search_mesh{8, 8, 8, 8};     // every objective evaluation is a full run
  DfnMesh final_mesh{20, 20, 20, 20};  // the reported before/after and the scores
  double rtol = 1e-6;
  std::vector<Effect> candidates{std::begin(kAllCandidates), std::end(kAllCandidates)};
  // One record: alternate blocks of it train and validate. Several records: the first one
  // trains, the others validate (cross-validation between cases).
  int blocks = 8;
  SelectionRules rules;
};

struct CaseResult {
  const Record* record = nullptr;
  std::string role;                  // "train+validate", "train" or "validate"
  std::vector<char> train, validate; // per sample
  Excitation excitation;
  std::vector<double> soc;
  ModelRun before, after;
  std::vector<double> residual_before_mv, residual_after_mv;
  double rmse_before_mv = 0, rmse_after_mv = 0, max_abs_before_mv = 0, max_abs_after_mv = 0;
  Characterisation char_before, char_after;
};

struct CandidateResult {
  Effect effect = Effect::none;
  bool available = true;
  double value = 0.0;
  double train_rmse_mv = 0.0;    // search mesh, corrected to the final mesh
  double heldout_rmse_mv = 0.0;  // score
  double rmse_after_mv = 0.0;    // all samples, final mesh
  double max_abs_after_mv = 0.0;
  int evaluations = 0;
  std::string note;
  std::vector<std::vector<double>> voltage_v;  // final-mesh model voltage per case
};

struct DiagnosisResult {
  Selection selection;
  std::vector<CaseResult> cases;
  std::vector<CandidateResult> candidates;  // "none" first
  double rmse_before_mv = 0, rmse_after_mv = 0, max_abs_before_mv = 0, max_abs_after_mv = 0;
  double heldout_before_mv = 0, heldout_after_mv = 0;
  std::string excitation_note;  // set when the records cannot separate effects
  double wall_s = 0.0;
};

using LogFn = std::function<void(const std::string&)>;

// Records must outlive the result (cases point at them).
DiagnosisResult diagnose(const CellParameters& cell, const std::vector<Record>& records,
                         const DiagnoseSettings& settings, const LogFn& log = {});

// The training and validation masks (exposed for tests).
void split_samples(std::size_t n, int blocks, std::vector<char>& train, std::vector<char>& validate);

}  // namespace bms::diagnosis
