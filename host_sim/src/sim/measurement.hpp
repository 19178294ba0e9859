#pragma once
// What a BMS sensor reports: the truth plus seeded Gaussian noise and, as undeclared effects,
// a current-sensor offset and gain error.
#include <cstdint>
#include <vector>

#include "sim/cycler.hpp"

namespace bms {

struct MeasurementModel {
  double noise_v_mv = 0.0;
  double noise_i_ma = 0.0;
  std::uint64_t seed = 1;
  double current_offset_a = 0.0;
  double current_gain = 0.0;  // relative: 0.01 = reads 1 % high
};

struct Measured {
  std::vector<double> current_a, voltage_v;
};

Measured measure(const std::vector<SampleRecord>& truth, const MeasurementModel& m);

}  // namespace bms
