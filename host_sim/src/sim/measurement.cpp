#include "sim/measurement.hpp"

#include <random>

namespace bms {

Measured measure(const std::vector<SampleRecord>& truth, const MeasurementModel& m) {
  // Separate streams so that changing one noise level leaves the other's draws unchanged.
  std::mt19937_64 rng_v(m.seed * 2 + 0), rng_i(m.seed * 2 + 1);
  std::normal_distribution<double> unit(0.0, 1.0);
  Measured out;
  out.current_a.reserve(truth.size());
  out.voltage_v.reserve(truth.size());
  for (const auto& s : truth) {
    const double nv = unit(rng_v), ni = unit(rng_i);
    out.voltage_v.push_back(s.voltage_v + 1e-3 * m.noise_v_mv * nv);
    out.current_a.push_back((1.0 + m.current_gain) * s.current_a + m.current_offset_a + 1e-3 * m.noise_i_ma * ni);
  }
  return out;
}

}  // namespace bms
