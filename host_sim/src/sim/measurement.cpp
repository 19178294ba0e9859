#include "sim/measurement.hpp"

namespace bms {

Measurer::Measurer(const MeasurementModel& m) : m_(m), rng_v_(m.seed * 2 + 0), rng_i_(m.seed * 2 + 1) {}

MeasuredSample Measurer::next(const SampleRecord& s) {
  const double nv = unit_(rng_v_), ni = unit_(rng_i_);
  return {(1.0 + m_.current_gain) * s.current_a + m_.current_offset_a + 1e-3 * m_.noise_i_ma * ni,
          s.voltage_v + 1e-3 * m_.noise_v_mv * nv};
}

Measured measure(const std::vector<SampleRecord>& truth, const MeasurementModel& m) {
  Measurer sensor(m);
  Measured out;
  out.current_a.reserve(truth.size());
  out.voltage_v.reserve(truth.size());
  for (const auto& s : truth) {
    const MeasuredSample x = sensor.next(s);
    out.current_a.push_back(x.current_a);
    out.voltage_v.push_back(x.voltage_v);
  }
  return out;
}

}  // namespace bms
