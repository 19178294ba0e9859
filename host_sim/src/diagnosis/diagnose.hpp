#pragma once
// The diagnosis: run the plain model on the measured records, fit candidate effects on the
// training part and score them on the held-out part, select up to three by forward selection
// (each further one must earn its place on held-out data), and give an honest answer: the
// effects when they explain the residual (held-out RMSE <= 20 % of the plain model's), `none`
// when the residual is already at its floor, `unexplained` otherwise, with where the residual
// left lives.
#include <functional>
#include <string>
#include <vector>

#include "diagnosis/adequacy.hpp"
#include "diagnosis/characterise.hpp"
#include "diagnosis/model_run.hpp"
#include "diagnosis/records.hpp"
#include "diagnosis/selection.hpp"

namespace bms::diagnosis {

struct DiagnoseSettings {
  DfnMesh search_mesh{8, 8, 8, 8};     // every objective evaluation is a full run
  DfnMesh final_mesh{20, 20, 20, 20};  // the reported before/after and the scores
  double rtol = 1e-6;
  // Search runs follow the current within this share of its largest value (see ModelSetup).
  double search_drive_tolerance = 0.0;
  std::vector<Effect> candidates{std::begin(kAllCandidates), std::end(kAllCandidates)};
  // One record: alternate blocks of it train and validate. Several records: each record is
  // validated by a fit on the others (leave one record out).
  int blocks = 8;
  int max_effects = 3;
  // Complexity penalty: a further effect must cut the held-out RMSE by this share and by
  // rules.min_absolute_gain_mv.
  double further_gain = 0.1;
  // A first effect too weak to be named alone opens a combination when it cuts the held-out
  // RMSE by this share (0: always explore from the best one).
  double open_gain = 0.1;
  // Combinations opened so are grown from this many of the best single effects.
  int beam = 2;
  // The held-out RMSE must fall to this share of the plain model's for `explained`.
  double explained_share = 0.2;
  SelectionRules rules;
  // Candidates (and the plain model's runs, the sensitivities) on this many threads; <= 0: one
  // per hardware thread. The answer and every number do not depend on it.
  int threads = 0;
};

struct CaseResult {
  const Record* record = nullptr;
  std::string role;                  // "train+validate" (one record) or "left out"
  std::vector<char> train, validate; // per sample (one record); validate = all when left out
  Excitation excitation;
  std::vector<double> soc;
  ModelRun before, after;
  std::vector<double> residual_before_mv, residual_after_mv;
  double rmse_before_mv = 0, rmse_after_mv = 0, max_abs_before_mv = 0, max_abs_after_mv = 0;
  double heldout_before_mv = 0, heldout_after_mv = 0;  // cross-validated
  Characterisation char_before, char_after;
  Adequacy adequacy_before, adequacy_after;
};

struct CandidateResult {
  Effect effect = Effect::none;
  bool available = true;
  Hypothesis fitted;             // the knobs fitted alone (first fold's values)
  double value = 0.0;            // the first knob's value (the resistance for rc_branch)
  double train_rmse_mv = 0.0;    // search mesh, corrected to the final mesh
  double heldout_rmse_mv = 0.0;  // score
  double rmse_after_mv = 0.0;    // all samples, final mesh (held-out predictions for several records)
  double max_abs_after_mv = 0.0;
  int evaluations = 0;
  std::string note;
};

// One step of the forward selection: every remaining candidate scored with the effects so far.
struct SelectionStep {
  std::vector<Effect> base;
  std::vector<std::pair<Effect, double>> scores;  // held-out RMSE per candidate
  Effect chosen = Effect::none;                  // none: stopped here
  std::string reason;
};

// Identifiability of the fitted knobs from the Fisher information J^T J / sigma^2 of the
// residual (sigma = the floor), in the search variable (log10 of a factor, else the value).
struct KnobIdentifiability {
  Effect knob = Effect::none;
  double value = 0.0;
  double sensitivity_mv = 0.0;   // RMS change of the model voltage per unit of the search variable
  double std_error = 0.0;        // in the search variable; relative (%) for a log10 one below
  double relative_std_pct = 0.0;
  double max_abs_correlation = 0.0;
  bool selected = false;
};

struct DiagnosisResult {
  Selection selection;                   // the first step's decision (kept for its reason)
  Effect answer = Effect::none;          // a knob, none or unexplained
  std::vector<Effect> effects;           // the explaining candidates, in order of selection
  Hypothesis model;                      // their fitted knobs (on all the data)
  bool explained = false;
  Hypothesis best_partial;               // unexplained: the best model reached and its numbers
  std::vector<Effect> best_partial_effects;
  double best_partial_heldout_mv = 0.0;
  std::string reason;
  std::vector<CaseResult> cases;
  std::vector<CandidateResult> candidates;  // "none" first
  std::vector<SelectionStep> steps;
  std::vector<KnobIdentifiability> identifiability;  // selected knobs first, then by sensitivity
  double rmse_before_mv = 0, rmse_after_mv = 0, max_abs_before_mv = 0, max_abs_after_mv = 0;
  double heldout_before_mv = 0, heldout_after_mv = 0;
  double floor_mv = 0.0;
  bool at_floor_before = false;
  std::string excitation_note;  // set when the records cannot separate effects
  int runs = 0;
  double wall_s = 0.0;
};

using LogFn = std::function<void(const std::string&)>;

// Records must outlive the result (cases point at them).
DiagnosisResult diagnose(const CellParameters& cell, const std::vector<Record>& records,
                         const DiagnoseSettings& settings, const LogFn& log = {});

// The training and validation masks (exposed for tests).
void split_samples(std::size_t n, int blocks, std::vector<char>& train, std::vector<char>& validate);

// --initial-soc: "full" (the cell's default state), "auto" (from the first voltage when the
// record starts at rest more than 5 mV away from the default state's open-circuit voltage;
// else full) or a state of charge in [0, 1] (1 = the default state). InputError otherwise.
void set_initial_state(Record& r, const CellParameters& cell, const std::string& spec);

}  // namespace bms::diagnosis
