#pragma once
// Baseline 2: per-cycle batch nonlinear least squares, the accuracy ceiling of any estimator
// that uses the same model and the same CC-charge voltage.
//
// Per cycle: the model runs from the state the previous cycle's fit left, with the previous
// fit's film resistance, up to the cycle's first CC-charge tick (detected mode, as the
// firmware sees it). Over the CC charge the film resistance is R(t) = a (constant) or
// a + b tau(t), tau running from -1 to 1 over the phase (linear), and (a, b) minimise
//   sum_k w_k (V_model,k(a, b) - y_k)^2,  w_k = 1 / (sigma_v^2 + sigma_i^2 (dV_k/dI_k)^2),
// by Gauss-Newton with forward-difference Jacobians (one model pass per parameter). In CC the
// model voltage is affine in R_film, so the second iteration only confirms the first. The
// fitted R(t) then drives the rest of the cycle (held at its end value), which carries the
// state into the next cycle. sigma of R(t_k) from the covariance (J' W J)^-1.
#include <vector>

#include "baselines/noise_levels.hpp"
#include "baselines/reduced_track.hpp"

namespace bms::baselines {

struct BatchConfig {
  bool linear = false;  // R_film linear in time within each CC charge
  int max_iterations = 6;
};

struct BatchCycle {
  int cycle = 0;
  std::size_t ticks = 0;         // CC-charge samples in the fit
  double r_a_ohm_m2 = 0.0;       // constant part
  double r_b_ohm_m2 = 0.0;       // change from mid-phase to the phase end (linear fit)
  double sigma_a_ohm_m2 = 0.0;
  double rms_residual_v = 0.0;   // weighted-fit residual, unweighted RMS
  double mean_residual_v = 0.0;
  int iterations = 0;
};

struct BatchRun {
  std::vector<double> r_est, r_sigma, model_voltage_v;
  std::vector<BatchCycle> cycles;
};

BatchRun run_batch(const Track& t, const NoiseLevels& noise, const BatchConfig& config, Cell cell,
                   double r_film_init_ohm_m2);

}  // namespace bms::baselines
