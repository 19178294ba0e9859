#pragma once
// The measured data prepared for the baselines: the firmware's reduced model driven over it
// exactly as the firmware's tick drives it (bms/fw/estimation/bms_core.hpp): the debounced mode from the
// measured signals, voltage-driven only when this sample's raw class confirms a CV phase,
// current-driven otherwise. Every baseline (EKF, batch fit, Cramer-Rao bound) walks the same
// track, so they differ only in how they choose the film resistance.
#include <cstddef>
#include <utility>
#include <vector>

#include "bms/fw/estimation/operating_mode.hpp"
#include "bms/fw/model/reduced_cell.hpp"
#include "estimation/estimate_run.hpp"

namespace bms::baselines {

using Cell = fw::ReducedCell<double>;

struct Track {
  const EstimateData* data = nullptr;
  double dt_s = 0.2;
  std::vector<fw::Mode> mode;       // debounced, from the measured signals
  std::vector<char> voltage_driven; // 1: the model follows the measured voltage this tick
  std::vector<char> scored;         // CC charge by detection (and by the file's mode column if any)
  // [first, last) tick of each cycle, in file order.
  std::vector<std::pair<std::size_t, std::size_t>> cycles;

  std::size_t size() const { return mode.size(); }
  // The model's input this tick: measured voltage when voltage-driven, current otherwise.
  double input(std::size_t i) const { return voltage_driven[i] ? data->voltage_v[i] : data->current_a[i]; }
};

// Needs evenly spaced samples (the firmware's fixed tick): InputError otherwise.
Track make_track(const EstimateData& d, double v_max, double v_min);

// One committed tick of the model with film resistance r_film_ohm_m2.
// RuntimeFailure when the model rejects the step (non-finite trial state).
fw::ModelTickResult<double> step(Cell& cell, const Track& t, std::size_t i, double r_film_ohm_m2);

// The same tick with the input replaced by `input` (A or V) and no validity check: callers
// step a copy of the model to take derivatives.
fw::ModelTickResult<double> step_with_input(Cell& cell, const Track& t, std::size_t i, double input,
                                            double r_film_ohm_m2);

// Terminal voltage of tick i (current-driven ticks) and its derivatives with respect to the
// film resistance and to this tick's measured current, by forward differences on copies of
// the model (the model's Scalar is a floating-point type, so dual numbers cannot pass through
// its state). The voltage is affine in R_film, so that difference is exact to round-off.
struct OutputSensitivity {
  double voltage_v, dv_dr_v_per_ohm_m2, dv_di_v_per_a;
};
OutputSensitivity output_sensitivity(const Cell& cell, const Track& t, std::size_t i, double r_film_ohm_m2);

inline constexpr double kFilmStepOhmM2 = 1e-6;  // 0.03 % of the paper cell's film
inline constexpr double kCurrentStepA = 1e-4;
inline constexpr double kVoltageStepV = 1e-5;

}  // namespace bms::baselines
