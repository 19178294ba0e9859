#pragma once
// Runs the truth DFN on a measured record with a hypothesis's run knobs (model switches, drive
// corrections, parameter re-fits) and gives the model voltage at every sample of the record.
// The measurement-structure knobs (post) are applied by the caller with apply_post.
#include <string>
#include <vector>

#include "cell/cell_parameters.hpp"
#include "diagnosis/effects.hpp"
#include "diagnosis/records.hpp"
#include "dfn/dfn_model.hpp"
#include "sim/cycler.hpp"

namespace bms::diagnosis {

struct ModelSetup {
  CellParameters cell;
  DfnMesh mesh;
  double rtol = 1e-6;
  // > 0: the driving current is replaced by piecewise-linear pieces within this share of its
  // largest value (coarse in time for the search runs: a drive cycle then needs a few hundred
  // kinks instead of one per sample; the search runs' difference from the final runs is taken
  // out by the mesh correction).
  double drive_tolerance_share = 0.0;
};

// The current as piecewise-linear pieces with knots on samples, each within tol_a of the
// samples it spans (changes over 25 % of the largest current stay steps).
std::vector<double> simplified_current(const std::vector<double>& t_s, const std::vector<double>& current_a,
                                       double tol_a);

struct ModelRun {
  std::vector<double> voltage_v;  // one per record sample; NaN after an early stop
  std::size_t samples_covered = 0;
  std::string note;               // why the model stopped early, if it did
  double wall_s = 0.0;
};

// The model starts from the record's initial state (record.initial_depth_ah, shifted by the
// hypothesis's initial_soc knob; the cell's default state when unset) at the record's first
// temperature (when the record has one; else the cell's ambient). CV segments are driven by
// their measured current too: the cycler's profile control is current-only.
ModelRun run_model(const ModelSetup& setup, const Record& record, const Hypothesis& h);
inline ModelRun run_model(const ModelSetup& setup, const Record& record, const EffectSetting& e) {
  return run_model(setup, record, Hypothesis{e});
}

// The cell at rest with depth_ah of charge taken from its default initial state (cyclable
// lithium conserved: each electrode's stoichiometry moves by depth / its capacity).
InitialConditions initial_state_at_depth(const CellParameters& cell, double depth_ah);
// The depth whose open-circuit voltage is v (bisection within the stoichiometry limits;
// clamped, with a note, when v lies outside the reachable range).
double depth_from_rest_voltage(const CellParameters& cell, double v, std::string* note = nullptr);

// Voltage residual (model - measured) in mV. Samples the model did not reach take the
// residual of its last sample, so a candidate cannot score better by stopping early.
std::vector<double> residual_mv(const std::vector<double>& model_v, const Record& record);

// Root mean square and maximum absolute value over the samples where use[k] is true
// (all when use is empty).
double rms(const std::vector<double>& x, const std::vector<char>& use = {});
double max_abs(const std::vector<double>& x, const std::vector<char>& use = {});

}  // namespace bms::diagnosis
