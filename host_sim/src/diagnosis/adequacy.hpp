#pragma once
// Is the residual left adequate? It is compared with the floor that no model of this cell can
// go below on this record: the voltage measurement's noise (estimated from the data) and the
// model's own numerical error (mesh and tolerance, estimated by Richardson extrapolation from
// the search and the final mesh). Its structure says where a model error lives: groups of
// samples (state of charge, current, time since a step) whose RMS is well above the floor, and
// the lag-1 autocorrelation (near 0 for noise, near 1 for a model error).
#include <string>
#include <vector>

#include "diagnosis/characterise.hpp"
#include "diagnosis/records.hpp"

namespace bms::diagnosis {

// Standard deviation of the voltage noise in mV from second differences of the measured
// voltage where the current is flat (robust: median absolute deviation), not below the ADC's
// resolution (the smallest voltage step, uniformly distributed rounding).
double measurement_noise_mv(const Record& r);

// Richardson estimate of the final mesh's own error (RMS, mV) from the plain model on the
// search and the final mesh: second-order finite volumes, error ~ h^2.
double numerical_error_mv(const std::vector<double>& final_v, const std::vector<double>& search_v, int search_n,
                          int final_n);

struct Adequacy {
  double noise_mv = 0.0, numerical_mv = 0.0, floor_mv = 0.0;
  double rmse_mv = 0.0;        // the residual judged
  double lag1_autocorrelation = 0.0;
  bool at_floor = false;       // rmse <= kFloorFactor x floor
  std::vector<ResidualGroup> above_floor;  // groups with RMS over kFloorFactor x floor, worst first
  std::string verdict;         // one sentence
};

// A residual within this factor of the floor is at the floor.
inline constexpr double kFloorFactor = 2.0;

Adequacy check_adequacy(const Record& r, const std::vector<double>& residual_mv, const Characterisation& ch,
                        double noise_mv, double numerical_mv);

}  // namespace bms::diagnosis
