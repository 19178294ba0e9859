#include "diagnosis/adequacy.hpp"
#include "io/statistics.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

namespace bms::diagnosis {

namespace {


// Normal-distribution consistency of the median absolute deviation.
constexpr double kMadToSigma = 1.4826;
// Voltage differences below this are the file's decimal round-off, not an ADC step.
constexpr double kRoundOffV = 1e-6;

}  // namespace

double measurement_noise_mv(const Record& r) {
  const std::size_t n = r.t_s.size();
  double imax = 0.0;
  for (double i : r.current_a) imax = std::max(imax, std::abs(i));
  const double step = 0.01 * imax + 1e-6;
  std::vector<double> d2;
  double quantum = HUGE_VAL;
  // Only where the current is flat over five samples (four small changes), as the drive's
  // jitter (sim/current_profile_run.cpp): where a smooth drive cycle's slope passes through
  // zero at a single sample, the voltage's second difference is the current's curvature times
  // the cell's resistance (0.7 mV as "noise" on the tests' drive cycle, whose noise is 0.05 mV).
  auto flat = [&](std::size_t k) { return std::abs(r.current_a[k + 1] - r.current_a[k]) <= step; };
  for (std::size_t k = 1; k + 1 < n; ++k) {
    const double dv = std::abs(r.voltage_v[k] - r.voltage_v[k - 1]);
    if (dv > kRoundOffV) quantum = std::min(quantum, dv);
    if (k < 2 || k + 2 >= n || !(flat(k - 2) && flat(k - 1) && flat(k) && flat(k + 1))) continue;
    // Second difference of white noise has variance 6 sigma^2; a smooth signal contributes
    // almost nothing at 1-10 s sampling.
    d2.push_back(r.voltage_v[k + 1] - 2.0 * r.voltage_v[k] + r.voltage_v[k - 1]);
  }
  const double rounding_v = std::isfinite(quantum) ? quantum / std::sqrt(12.0) : 0.0;
  // Without a flat stretch (a current that changes at every sample) the white noise cannot be
  // told from the current's curvature: the file's own resolution is the floor left, not zero.
  if (d2.empty()) return 1e3 * rounding_v;
  const double med = stats::median(d2);
  for (double& x : d2) x = std::abs(x - med);
  const double sigma_v = kMadToSigma * stats::median(d2) / std::sqrt(6.0);
  return 1e3 * std::max(sigma_v, rounding_v);
}

double numerical_error_mv(const std::vector<double>& final_v, const std::vector<double>& search_v, int search_n,
                          int final_n) {
  if (search_n >= final_n) return 0.0;
  const double ratio = std::pow(static_cast<double>(search_n) / final_n, 2.0);
  double s = 0.0;
  std::size_t n = 0;
  for (std::size_t k = 0; k < std::min(final_v.size(), search_v.size()); ++k) {
    if (!std::isfinite(final_v[k]) || !std::isfinite(search_v[k])) continue;
    const double d = 1e3 * (final_v[k] - search_v[k]);
    s += d * d;
    ++n;
  }
  return n ? std::sqrt(s / static_cast<double>(n)) * ratio / (1.0 - ratio) : 0.0;
}

Adequacy check_adequacy(const Record& r, const std::vector<double>& res, const Characterisation& ch, double noise_mv,
                        double numerical_mv) {
  (void)r;
  Adequacy a;
  a.noise_mv = noise_mv;
  a.numerical_mv = numerical_mv;
  a.floor_mv = std::hypot(noise_mv, numerical_mv);
  double s2 = 0.0, mean = 0.0;
  for (double x : res) mean += x;
  mean /= static_cast<double>(std::max<std::size_t>(res.size(), 1));
  double c0 = 0.0, c1 = 0.0;
  for (std::size_t k = 0; k < res.size(); ++k) {
    s2 += res[k] * res[k];
    c0 += (res[k] - mean) * (res[k] - mean);
    if (k > 0) c1 += (res[k] - mean) * (res[k - 1] - mean);
  }
  a.rmse_mv = res.empty() ? 0.0 : std::sqrt(s2 / static_cast<double>(res.size()));
  a.lag1_autocorrelation = c0 > 0 ? c1 / c0 : 0.0;
  a.at_floor = a.rmse_mv <= kFloorFactor * a.floor_mv;
  for (const auto& g : ch.groups)
    if (g.dimension != "mode" && g.dimension != "dvdt" && g.rms_mv > kFloorFactor * a.floor_mv) a.above_floor.push_back(g);
  std::sort(a.above_floor.begin(), a.above_floor.end(),
            [](const ResidualGroup& x, const ResidualGroup& y) { return x.rms_mv > y.rms_mv; });
  if (a.at_floor) {
    a.verdict = fmt::format("RMSE {:.3f} mV is within {:g}x the floor {:.3f} mV (noise {:.3f}, numerical {:.3f} mV)",
                            a.rmse_mv, kFloorFactor, a.floor_mv, noise_mv, numerical_mv);
  } else {
    std::string where;
    for (std::size_t k = 0; k < std::min<std::size_t>(3, a.above_floor.size()); ++k)
      where += fmt::format("{}{} {} ({:.3g} mV RMS, mean {:+.3g})", k ? "; " : "", a.above_floor[k].dimension,
                           a.above_floor[k].label, a.above_floor[k].rms_mv, a.above_floor[k].mean_mv);
    a.verdict = fmt::format(
        "RMSE {:.3f} mV is {:.0f}x the floor {:.3f} mV (noise {:.3f}, numerical {:.3f} mV); lag-1 autocorrelation "
        "{:.2f} ({}); largest: {}",
        a.rmse_mv, a.floor_mv > 0 ? a.rmse_mv / a.floor_mv : HUGE_VAL, a.floor_mv, noise_mv, numerical_mv,
        a.lag1_autocorrelation, a.lag1_autocorrelation > 0.5 ? "a structured model error, not noise" : "noise-like",
        where.empty() ? "-" : where);
  }
  return a;
}

}  // namespace bms::diagnosis
