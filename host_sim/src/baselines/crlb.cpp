#include "baselines/crlb.hpp"

#include <cmath>
#include <limits>

namespace bms::baselines {

BoundRun cramer_rao_bound(const Track& t, const NoiseLevels& noise, Cell cell, double r_film_init_ohm_m2) {
  const EstimateData& d = *t.data;
  const bool have_truth = !d.r_film_true_ohm_m2.empty();
  BoundRun out;
  out.model_voltage_v.resize(t.size());
  const double var_v = noise.sigma_v_v * noise.sigma_v_v;
  const double var_i = noise.sigma_i_a * noise.sigma_i_a;
  for (const auto& [first, last] : t.cycles) {
    CycleBound b;
    b.cycle = d.cycle[first];
    double r_sum = 0.0;
    for (std::size_t i = first; i < last; ++i) {
      const double r = have_truth ? d.r_film_true_ohm_m2[i] : r_film_init_ohm_m2;
      if (t.scored[i]) {
        const OutputSensitivity s = output_sensitivity(cell, t, i, r);
        b.fisher_per_ohm2_m4 += s.dv_dr_v_per_ohm_m2 * s.dv_dr_v_per_ohm_m2 / (var_v + var_i * s.dv_di_v_per_a * s.dv_di_v_per_a);
        r_sum += r;
        ++b.ticks;
      }
      out.model_voltage_v[i] = step(cell, t, i, r).voltage_v;
    }
    b.bound_ohm_m2 = b.fisher_per_ohm2_m4 > 0.0 ? 1.0 / std::sqrt(b.fisher_per_ohm2_m4)
                                               : std::numeric_limits<double>::infinity();
    b.r_film_ref_ohm_m2 = b.ticks > 0 ? r_sum / static_cast<double>(b.ticks) : r_film_init_ohm_m2;
    b.rel_pct = 100.0 * b.bound_ohm_m2 / b.r_film_ref_ohm_m2;
    out.cycles.push_back(b);
  }
  return out;
}

}  // namespace bms::baselines
