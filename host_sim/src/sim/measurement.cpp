#include "sim/measurement.hpp"

namespace bms {

// The temperature stream's seed is apart from the voltage and current streams' (2 seed, 2 seed + 1)
// for every seed, so adding temperature noise leaves their draws as they were.
constexpr std::uint64_t kTemperatureStream = 0x9E3779B97F4A7C15ull;

Measurer::Measurer(const MeasurementModel& m)
    : m_(m), rng_v_(m.seed * 2 + 0), rng_i_(m.seed * 2 + 1), rng_t_(m.seed ^ kTemperatureStream) {}

MeasuredSample Measurer::next(const SampleRecord& s) {
  const double nv = unit_(rng_v_), ni = unit_(rng_i_);
  const double nt = m_.noise_t_k > 0.0 ? unit_t_(rng_t_) : 0.0;
  return {(1.0 + m_.current_gain) * s.current_a + m_.current_offset_a + 1e-3 * m_.noise_i_ma * ni,
          s.voltage_v + m_.voltage_offset_v + 1e-3 * m_.noise_v_mv * nv, s.temperature_k + m_.temperature_offset_k + m_.noise_t_k * nt};
}

Measured measure(const std::vector<SampleRecord>& truth, const MeasurementModel& m) {
  Measurer sensor(m);
  Measured out;
  out.current_a.reserve(truth.size());
  out.voltage_v.reserve(truth.size());
  out.temperature_k.reserve(truth.size());
  for (const auto& s : truth) {
    const MeasuredSample x = sensor.next(s);
    out.current_a.push_back(x.current_a);
    out.voltage_v.push_back(x.voltage_v);
    out.temperature_k.push_back(x.temperature_k);
  }
  return out;
}

}  // namespace bms
