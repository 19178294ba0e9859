#pragma once
// `bmssim baseline`: the reference estimators of the film resistance that RCSI is judged
// against, on the same data and the same reduced model: an augmented-state
// EKF, a per-cycle batch least-squares fit, and the Cramer-Rao lower bound.
#include <string>
#include <vector>

#include "baselines/augmented_ekf.hpp"
#include "baselines/batch_fit.hpp"
#include "baselines/crlb.hpp"
#include "baselines/noise_levels.hpp"
#include "estimation/estimate_run.hpp"
#include "sim/cycler.hpp"

namespace bms::baselines {

struct BaselineOptions {
  std::string method = "ekf";  // ekf | batch | crlb
  double sigma_v_v = -1.0;     // < 0: estimate from the data (floor 0.02 mV)
  double sigma_i_a = -1.0;     // < 0: estimate from the data
  double r_film_init_ohm_m2 = -1.0;  // < 0: the paper cell's initial film
  InitialConditions ic;        // of the model (not the truth)
  EkfConfig ekf;
  BatchConfig batch;
};

struct BaselineResult {
  std::string method;
  std::vector<EstimateRow> rows;   // r_film_est is NaN for the bound
  std::vector<double> r_sigma_ohm_m2;
  std::vector<CycleScore> scores; // empty for the bound
  std::vector<CycleBound> bounds;
  std::vector<BatchCycle> batch_cycles;
  NoiseLevels noise;
  std::size_t ekf_updates = 0, ekf_gated = 0;
  double wall_s = 0.0;
};

// Throws InputError for bad options (naming the option) and RuntimeFailure if the model fails.
BaselineResult run_baseline(const EstimateData& data, const BaselineOptions& o);

}  // namespace bms::baselines
