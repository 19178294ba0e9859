#pragma once
// The estimate over a cell's life beside the cycler's own per-cycle numbers: state of health
// (capacity / first capacity) against the measured discharge capacity's, resistance growth
// against the cycler's internal-resistance growth; aging.csv and two plots.
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "estimation/charges.hpp"
#include "io/cycler_formats.hpp"

namespace bms {

struct AgingRow {
  int cycle;
  double capacity_est_ah, capacity_sd_ah, soh_est, counted_ah, soh_counted, r_growth_est_ohm, r_step_growth_ohm,
      r_discharge_step_growth_ohm, r_discharge_onset_growth_ohm;
  double discharge_meas_ah, soh_meas, ir_meas_ohm, ir_growth_meas_ohm;
  bool learned;
  bool counted_complete;  // ChargeReport::counted_complete: the count spans a whole charge
};

struct LineFit {
  std::size_t n = 0;
  double pearson = std::nan(""), slope = std::nan(""), intercept = std::nan("");
};
// Least squares y = intercept + slope x and Pearson's r over the pairs where both are finite.
LineFit fit_line(const std::vector<double>& x, const std::vector<double>& y);

struct AgingComparison {
  std::vector<AgingRow> rows;  // one per CC charge (learned or not) whose cycle the cycler reported
  double soh_mae_pp = std::nan(""), soh_max_abs_pp = std::nan("");  // the estimate's capacity_ah
  double soh_counted_mae_pp = std::nan("");                           // the counted charge's
  std::size_t cycles_scored = 0;  // rows with a capacity (ChargeReport::capacity_ah not null)
  std::string capacity_source;  // of the compared charges' capacity_ah: estimator, counted or mixed
  LineFit film_vs_ir, step_vs_ir, discharge_step_vs_ir, discharge_onset_vs_ir;  // y = estimate's growth, x = the cycler's IR growth
};

// Cycles whose measured discharge is under 5 % of the largest (a cycle cut by the end of a
// file) are left out; the references are the first charge left in.
AgingComparison compare_aging(const std::vector<ChargeReport>& charges, const std::vector<CyclerCycleStat>& cycler);

nlohmann::json aging_json(const AgingComparison& a);

// aging.csv, plots.gp, capacity.png, resistance.png in `dir`. Returns "" or what went wrong
// with the plots (gnuplot missing or failing: the CSV is written anyway).
std::string write_aging_outputs(const std::filesystem::path& dir, const AgingComparison& a);

}  // namespace bms
