#pragma once
// `bmssim diagnose --write-cell`: the input cell's BPX file with the effects a diagnosis
// selected, at their fitted sizes, so that `simulate`, `estimate`, `diagnose` and `cell-config`
// take the augmented cell with --cell FILE. Parameter re-fits scale the BPX fields themselves;
// the model switches go into the "User-defined" keys the BPX reader reads (CellEffectParameters,
// docs/parameters.md). Sensor errors, the logging's time skew, an RC branch and the record's
// start state are not properties of the cell: a hypothesis holding one is refused, naming it.
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "cell/cell_parameters.hpp"
#include "diagnosis/effects.hpp"

namespace bms::diagnosis {

struct AugmentedCell {
  nlohmann::json bpx;                 // valid only when refused is empty
  std::vector<std::string> added;     // one line per knob: effect, size, where it went
  nlohmann::json added_json = nlohmann::json::array();  // the same for summary.json
  std::string refused;                // one line naming the effect a cell cannot carry
};

// Why `e` cannot be written into a cell file ("" when it can).
std::string not_a_cell_property(Effect e, double value);

// The input cell (its BPX JSON and as read) plus the knobs of h. Contact resistance adds to the
// cell's own; every other knob replaces (hysteresis, thermal, particle size) or scales (the
// re-fits) the input's value.
AugmentedCell augment_cell(const nlohmann::json& input_bpx, const CellParameters& input, const Hypothesis& h);

}  // namespace bms::diagnosis
