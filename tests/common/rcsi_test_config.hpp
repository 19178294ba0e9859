#pragma once
// The RCSI estimator configuration the state, NVM and fuzz tests share: n_c = 2, a slightly
// forgetting RLS, theta(0) holding the film, the paper cell's initial film, an admissible film
// range, the paper's H and P(0) (the Config defaults).
#include "bms/fw/model/paper_cell.hpp"
#include "bms/fw/estimation/rcsi_estimator.hpp"

namespace bms::test {

template <class Estimator>
typename Estimator::Config rcsi_test_config() {
  static_assert(Estimator::kNumRegressors == 4, "theta(0) below is written for n_c = 2");
  typename Estimator::Config c;
  c.lambda = 0.999;
  c.theta0 << 1.0, 0.0, -1e-10, 0.0;
  c.r_film_init_ohm_m2 = bms::fw::paper::kInitialFilm_ohm_m2;
  c.j_side_init_a_m3 = -10.0;
  c.r_film_min_ohm_m2 = 1e-4;
  c.r_film_max_ohm_m2 = 1e-1;
  return c;
}

}  // namespace bms::test
