#pragma once
// Measurement-noise levels the baselines weight the data with: given on the command line, or
// estimated from the data itself.
#include <string>

#include "baselines/reduced_track.hpp"

namespace bms::baselines {

struct NoiseLevels {
  double sigma_v_v = 0.0;   // voltage sensor noise (std)
  double sigma_i_a = 0.0;   // current sensor noise (std)
  std::string v_source, i_source;  // "option" | "estimated" | "floor"
};

// The paper's smallest voltage noise: the floor of the voltage estimate, because on noise-free
// data the estimate is round-off and a weight of 1/round-off^2 would make every baseline and
// the bound claim an accuracy no sensor gives.
inline constexpr double kVoltageNoiseFloorV = 0.02e-3;

// Robust estimates over the CC-charge samples (where the current is constant and the voltage
// smooth at the tick scale): sigma_i from first differences of the current, sigma_v from
// second differences of the voltage, each as 1.4826 MAD / sqrt(sum of squared difference
// weights). The model's curvature over 0.4 s is far below 0.01 mV, so it does not bias sigma_v.
// A negative option value means "estimate".
NoiseLevels choose_noise(const Track& t, double sigma_v_option_v, double sigma_i_option_a);

}  // namespace bms::baselines
