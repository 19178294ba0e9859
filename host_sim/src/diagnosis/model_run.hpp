#pragma once
// Runs the truth DFN on a measured record with one candidate effect added, and gives the
// model voltage at every sample of the record.
#include <string>
#include <vector>

#include "cell/cell_parameters.hpp"
#include "diagnosis/effects.hpp"
#include "diagnosis/records.hpp"
#include "dfn/dfn_model.hpp"

namespace bms::diagnosis {

struct ModelSetup {
  CellParameters cell;
  DfnMesh mesh;
  double rtol = 1e-6;
};

struct ModelRun {
  std::vector<double> voltage_v;  // one per record sample; NaN after an early stop
  std::size_t samples_covered = 0;
  std::string note;               // why the model stopped early, if it did
  double wall_s = 0.0;
};

// The model starts from the cell's default initial state at the record's first temperature
// (when the record has one; else the cell's ambient). CV segments are driven by their
// measured current too: the cycler's profile control is current-only, and the current
// measured in CV carries the same information as the voltage the charger held.
ModelRun run_model(const ModelSetup& setup, const Record& record, const EffectSetting& effect);

// Voltage residual (model - measured) in mV. Samples the model did not reach take the
// residual of its last sample, so a candidate cannot score better by stopping early.
std::vector<double> residual_mv(const std::vector<double>& model_v, const Record& record);

// Root mean square and maximum absolute value over the samples where use[k] is true
// (all when use is empty).
double rms(const std::vector<double>& x, const std::vector<char>& use = {});
double max_abs(const std::vector<double>& x, const std::vector<char>& use = {});

}  // namespace bms::diagnosis
