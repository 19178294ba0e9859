#pragma once
// What a BMS sensor reports: the truth plus seeded Gaussian noise and, as undeclared effects,
// a current-sensor offset and gain error.
#include <cstdint>
#include <random>
#include <vector>

#include "sim/cycler.hpp"

namespace bms {

struct MeasurementModel {
  double noise_v_mv = 0.0;
  double noise_i_ma = 0.0;
  std::uint64_t seed = 1;
  double current_offset_a = 0.0;
  double current_gain = 0.0;  // relative: 0.01 = reads 1 % high
  double noise_t_k = 0.0;         // temperature sensor noise, standard deviation (K)
  double temperature_offset_k = 0.0;  // temperature sensor offset (K): reads this much high
  double voltage_offset_v = 0.0;      // voltage sensor offset (V): reads this much high
};

struct Measured {
  std::vector<double> current_a, voltage_v, temperature_k;
};

struct MeasuredSample {
  double current_a, voltage_v, temperature_k;
};

// The sensor applied one sample at a time, in order: the same draws as measure() on the whole
// series, so a streamed run and a whole one measure alike.
class Measurer {
 public:
  explicit Measurer(const MeasurementModel& m);
  MeasuredSample next(const SampleRecord& truth);

 private:
  MeasurementModel m_;
  // Separate streams so that changing one noise level leaves the other's draws unchanged.
  std::mt19937_64 rng_v_, rng_i_, rng_t_;
  std::normal_distribution<double> unit_{0.0, 1.0};
  std::normal_distribution<double> unit_t_{0.0, 1.0};  // its own: a shared one caches the other pair's draw
};

Measured measure(const std::vector<SampleRecord>& truth, const MeasurementModel& m);

}  // namespace bms
