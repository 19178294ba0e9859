#pragma once
// The contract's `charges` of `estimate`: one entry per constant-current charge the firmware
// learned in, from the estimator's rows and the measured samples only (never a truth column).
#include <vector>

#include <nlohmann/json.hpp>

#include "cell/cell_parameters.hpp"
#include "estimation/estimate_run.hpp"

namespace bms {

struct ChargeReport {
  int index;   // 1-based over the learned charges
  int cycle;   // the data's cycle at the charge's start
  double t_start_s, t_end_s;  // the CC phase as the firmware's mode detector saw it
  // The open-circuit capacity and its 1-sigma as the estimator identified them at the CC end
  // (from the identified lithium inventory); where the estimator identifies none (the paper's
  // RCSI path, learning off) the counted charge below stands in (capacity_source says which).
  double capacity_ah, capacity_sd_ah;
  bool capacity_estimated;
  // The count spans a whole charge: from a discharge to the lower voltage limit to a rest or a
  // discharge (not part-way, not cut by a power cycle). Else capacity_ah is null where counted.
  bool counted_complete;
  // Charge counted (trapezoids on the measured current) from the CC start to the end of the
  // charge (current back to rest, or a discharge). sd: half the charge interpolated across
  // logging gaps inside it (the current there is not measured), plus a 0.1 % sensor gain.
  double counted_ah, counted_sd_ah;
  double r_film_ohm_m2, r_film_sd_ohm_m2;  // at the CC end; sd NaN where the estimator has none
  double r_growth_ohm;  // (film - film at the first learned charge's end) / negative surface area
  // Measured beside the film: the voltage step at the charge's onset over the current step,
  // (V first under current - V last at rest) / |I|: a lumped resistance at the sample interval.
  double r_step_ohm;
  // The same at the onset of the discharge that follows the charge (from rest, the cell full):
  // (V last at rest - V first under discharge) / I, a DC resistance at a repeatable state of
  // charge, which the charge's onset (from wherever the discharge left the cell) is not.
  double r_discharge_step_ohm;
  // The same step's resistance at the step's instant (ohmic and charge transfer, no diffusion):
  // extrapolated from the first two samples under the discharge on the square root of the time
  // since the step began, which the cycler logs (Arbin Step_Time); NaN where it is not logged.
  // The cycler's pulse resistance is an instantaneous one: this is what compares with it.
  double r_discharge_onset_ohm;
  bool learned;  // the firmware learned in this CC phase
};

// The negative electrode's particle surface (m2): a film resistance in ohm m2 over it is ohm.
double negative_surface_area_m2(const CellParameters& cell);

// `learned_only`: the contract's list (CC phases the firmware learned in); false: every CC phase
// the firmware's mode detector found (the control run's comparison with the cycler).
std::vector<ChargeReport> find_charges(const std::vector<EstimateRow>& rows, const EstimateData& data,
                                       const CellParameters& cell, bool learned_only = true);

// The contract's entry (index, t_start_s, t_end_s, capacity_ah, capacity_sd_ah, r_film_ohm_m2,
// r_film_sd_ohm_m2, r_growth_ohm) plus cycle, capacity_source, counted_ah, counted_sd_ah and
// r_step_ohm; NaN as null.
nlohmann::json charges_json(const std::vector<ChargeReport>& charges);

}  // namespace bms
