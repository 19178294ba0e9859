#pragma once
// Cramer-Rao lower bound on the film resistance per cycle: the physical limit of any unbiased
// estimate of one film resistance per CC charge from that charge's voltage samples.
//
//   I_c = sum over the cycle's CC-charge ticks of (dV_k/dR_film)^2 / (sigma_v^2 + sigma_i^2 (dV_k/dI_k)^2)
//   std(R_film estimate) >= 1 / sqrt(I_c)
//
// Current noise enters through the tick's own current (the model is driven by the measured
// current). Its effect through the state of later ticks is left out: 1 mC per tick at 5 mA,
// but it adds up as a random walk (about 0.1 C over a charge), so at large current noise the
// bound is optimistic. The sensitivities are taken on
// the model driven with the true film resistance when the file has it (a bound is evaluated
// at the true parameter), else with the initial film resistance.
#include <vector>

#include "baselines/noise_levels.hpp"
#include "baselines/reduced_track.hpp"

namespace bms::baselines {

struct CycleBound {
  int cycle = 0;
  std::size_t ticks = 0;
  double fisher_per_ohm2_m4 = 0.0;
  double bound_ohm_m2 = 0.0;       // 1 / sqrt(I_c); infinite when the cycle has no CC charge
  double r_film_ref_ohm_m2 = 0.0;  // mean true (or assumed) film over the cycle's CC charge
  double rel_pct = 0.0;            // bound / r_film_ref in percent
};

struct BoundRun {
  std::vector<CycleBound> cycles;
  std::vector<double> model_voltage_v;  // per tick, the model driven as described above
};

BoundRun cramer_rao_bound(const Track& t, const NoiseLevels& noise, Cell cell, double r_film_init_ohm_m2);

}  // namespace bms::baselines
