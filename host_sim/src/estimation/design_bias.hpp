#pragma once
// The firmware reduced model's design-time calibration for any cell: its voltage bias in CC
// charge per ampere of charge current (ohm), the median over the charges' ticks after the best
// profile's warm-up, against a converged DFN (40/40 volumes, rtol 1e-9) of the *nominal* cell
// (its own film, growth law and inventory; nothing of a cell in use; without the cell's own effects
// of CellParameters::effects) over 3 CCCV cycles at 1C (CV to C/10). Its coverage (the charge
// currents and starts where the bias fits the nominal cell: ModelBiasTables::covers) from the
// same DFN at 0.7, 0.5 and 0.3C.
// Beside the constant, its state-of-charge-dependent part: a ModelBiasTable over the model's mean
// anode stoichiometry, each knot the median of (z / -I less the constant) over the same ticks
// within half a knot step of it (a median: the charge's end can be 100 mV off on a knee), a knot
// without ticks interpolated from its neighbours. The same table at the nominal DFN's inventory 1 %
// below and above nominal (the model placed there too; less the nominal constant): the levels the
// firmware reads at the model's identified inventory (ModelBiasTables). The paper cell runs on its
// constant alone.
// What scripts/calibrate-model-bias.sh measures for the paper cell, for every other cell by one
// call: `bmssim cell-config --cell X` prints it, `estimate --cell X --model reduced` uses it.
#include <array>
#include <cstddef>
#include <string>
#include <vector>

#include "bms/fw/model/model_bias_table.hpp"
#include "cell/cell_parameters.hpp"

namespace bms {

struct EstimateOptions;

struct DesignBias {
  double bias_ohm = 0.0;
  fw::ModelBiasTables<double> table{};  // the part that varies with the state of charge and inventory (added)
  std::size_t ticks = 0;  // CC-charge ticks the median is over
  // The nominal run's residual less the bias over those ticks, 10th / 50th / 90th percentile [V]:
  // with the constant alone, and with the constant and the table.
  std::array<double, 3> residual_constant_v{}, residual_table_v{};
  // Per knot, the 90th percentile of |residual less the constant and the table| over its ticks [V]
  // (0 for a knot without ticks): the misfit that sets the nominal level's x_trusted_last.
  std::array<double, fw::kModelBiasKnots> knot_misfit_v{};
  std::vector<std::string> level_notes;  // a level that stayed the nominal one, and why
  // The coverage's measurements (table.covered_charge_a_min, table.constant_alone_covered): per
  // lower charge rate, the 90th percentile of |residual less the 1C bias and table| over its CC
  // charges within the trusted span [V] (+inf: the nominal DFN could not run it); the same of the
  // constant alone at 1C.
  struct RateFit {
    double c_rate;
    double fit_p90_v;
  };
  std::vector<RateFit> coverage;
  double constant_alone_fit_p90_v = 0.0;
  double wall_s = 0.0;
};

DesignBias design_time_bias(const CellParameters& nominal);

// The bias an estimate of the reduced model runs with: the calibration's constant and table, for
// the best profile unless --model-bias-ohm gave a constant (then that constant is the whole bias).
void use_design_bias(EstimateOptions& o, const DesignBias& b);

// The table of the ticks' (stoichiometry, z / -I less the constant): knots over the ticks' range.
// Exposed for the tests; throws RuntimeFailure without ticks.
// Per knot of t, the 90th percentile of |residual_v| over the ticks nearest it (0: no tick).
std::array<double, fw::kModelBiasKnots> knot_misfit_v(const fw::ModelBiasTable<double>& t,
                                                     const std::vector<double>& stoich,
                                                     const std::vector<double>& residual_v);
// The trusted span's end: the upper edge of the highest knot whose misfit is within tolerance_v
// after every knot above it failed; +inf when the last knot fits (or the table is off).
double trusted_span_end(const fw::ModelBiasTable<double>& t, const std::array<double, fw::kModelBiasKnots>& misfit_v,
                        double tolerance_v);

fw::ModelBiasTable<double> bias_table_of(const std::vector<double>& stoich, const std::vector<double>& ratio_ohm);

}  // namespace bms
