#pragma once
// The firmware reduced model's design-time calibration for any cell: its voltage bias in CC
// charge per ampere of charge current (ohm), the median over the charges' ticks after the best
// profile's warm-up, against a converged DFN (40/40 volumes, rtol 1e-9) of the *nominal* cell
// (its own film, growth law and inventory; nothing of a cell in use; without the cell's own effects
// of CellParameters::effects) over 3 CCCV cycles at 1C (CV to C/10).
// What scripts/calibrate-model-bias.sh measures for the paper cell, for every other cell by one
// call: `bmssim cell-config --cell X` prints it, `estimate --cell X --model reduced` uses it.
#include "cell/cell_parameters.hpp"

namespace bms {

struct DesignBias {
  double bias_ohm = 0.0;
  std::size_t ticks = 0;  // CC-charge ticks the median is over
  double wall_s = 0.0;
};

DesignBias design_time_bias(const CellParameters& nominal);

}  // namespace bms
