#include "baselines/noise_levels.hpp"
#include "io/statistics.hpp"

#include <algorithm>
#include <cmath>
#include <vector>

namespace bms::baselines {

namespace {

double mad_sigma(std::vector<double> x) {
  if (x.size() < 10) return 0.0;
  const double m = stats::median(x);
  for (double& v : x) v = std::abs(v - m);
  return 1.4826 * stats::median(x);
}

}  // namespace

NoiseLevels choose_noise(const Track& t, double sigma_v_option_v, double sigma_i_option_a) {
  const EstimateData& d = *t.data;
  std::vector<double> d1, d2;
  for (std::size_t i = 1; i + 1 < t.size(); ++i) {
    const bool cc = t.mode[i - 1] == fw::Mode::cc_charge && t.mode[i] == fw::Mode::cc_charge &&
                    t.mode[i + 1] == fw::Mode::cc_charge;
    if (!cc) continue;
    d1.push_back(d.current_a[i] - d.current_a[i - 1]);
    d2.push_back(d.voltage_v[i + 1] - 2.0 * d.voltage_v[i] + d.voltage_v[i - 1]);
  }
  NoiseLevels n;
  if (sigma_v_option_v >= 0.0) {
    n.sigma_v_v = sigma_v_option_v;
    n.v_source = "option";
  } else {
    const double est = mad_sigma(d2) / std::sqrt(6.0);
    n.sigma_v_v = std::max(est, kVoltageNoiseFloorV);
    n.v_source = est >= kVoltageNoiseFloorV ? "estimated" : "floor";
  }
  if (sigma_i_option_a >= 0.0) {
    n.sigma_i_a = sigma_i_option_a;
    n.i_source = "option";
  } else {
    n.sigma_i_a = mad_sigma(d1) / std::sqrt(2.0);
    n.i_source = "estimated";
  }
  return n;
}

}  // namespace bms::baselines
