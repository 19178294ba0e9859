#pragma once
// Hidden truth parameters (contract: simulate, "Hidden truth parameters"): what
// `--set NAME=VALUE` changes in the truth model for one run, so that the simulated cell can
// differ from the nominal one the estimator knows. One table holds every name, its unit and
// its physical range; the rest of the simulator only sees a changed CellParameters.
#include <map>
#include <string>
#include <string_view>
#include <vector>

#include <nlohmann/json.hpp>

#include "cell/cell_parameters.hpp"

namespace bms {

struct TruthParameter {
  const char* name;
  const char* unit;  // "-" for a factor
  double min_value, max_value;
  bool min_excluded;  // (min, max] rather than [min, max]
  bool needs_side_reaction;
  const char* meaning;
};

// Every settable parameter, in the order --list-params prints them.
const std::vector<TruthParameter>& truth_parameters();

// "[233.15, 353.15]" or "(0, 100]".
std::string range_text(const TruthParameter& p);

// The value the truth uses when nothing is set: the cell's own, or 1 for a factor.
double nominal_truth_value(const CellParameters& cell, std::string_view name);

// --list-params: one line per parameter (name, nominal value for this cell, unit, range,
// meaning), after one '#' line naming the cell.
std::string truth_parameter_listing(const CellParameters& cell);

class TruthSettings {
 public:
  // Parses NAME=VALUE assignments. InputError naming the parameter (and its range) for an
  // unknown name, a missing '=', a value that is not a finite number, a value outside the
  // range, or a name given twice.
  static TruthSettings parse(const std::vector<std::string>& assignments);

  bool is_set(std::string_view name) const { return values_.find(name) != values_.end(); }
  // The value this run uses: the one set, else the cell's nominal.
  double value(const CellParameters& nominal, std::string_view name) const;
  // The truth's cell: the nominal one with every set value applied. InputError if a value
  // does not apply to this cell (a side-reaction parameter on a cell without one) or if no
  // equilibrium state has the asked lithium inventory.
  CellParameters apply(const CellParameters& nominal) const;
  // {"name": value used, ...} for every parameter (summary.json "parameters").
  nlohmann::json values_json(const CellParameters& nominal) const;

 private:
  std::map<std::string, double, std::less<>> values_;
};

// The cell at rest in equilibrium with `inventory_scale` times the cyclable (solid) lithium of
// its initial state and the same open-circuit voltage: new uniform initial stoichiometries of
// both electrodes, found by bisection. InputError if none lies within the stoichiometry limits.
void scale_initial_inventory(CellParameters& cell, double inventory_scale);

}  // namespace bms
