#include "baselines/reduced_track.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "bms/fw/mode_detector.hpp"
#include "io/input_error.hpp"

namespace bms::baselines {

namespace {

// Times in a file carry round-off (3276.6000000000004): the tick is the median step rounded
// to 1 ns, as `bmssim estimate` does, so both run the model with the same dt.
double fixed_tick(const EstimateData& d) {
  std::vector<double> dt(d.t_s.size() - 1);
  for (std::size_t i = 1; i < d.t_s.size(); ++i) dt[i - 1] = d.t_s[i] - d.t_s[i - 1];
  std::nth_element(dt.begin(), dt.begin() + static_cast<long>(dt.size() / 2), dt.end());
  const double med = dt[dt.size() / 2];
  for (std::size_t i = 1; i < d.t_s.size(); ++i) {
    const double s = d.t_s[i] - d.t_s[i - 1];
    if (std::abs(s - med) > 0.01 * med)
      throw InputError(fmt::format("{}: the reduced model runs at a fixed tick; samples must be evenly spaced "
                                   "(median {} s) but t_s = {} s follows {} s after the previous sample",
                                   d.source, med, d.t_s[i], s));
  }
  return std::round(med * 1e9) / 1e9;
}

}  // namespace

Track make_track(const EstimateData& d, double v_max, double v_min) {
  Track t;
  t.data = &d;
  t.dt_s = fixed_tick(d);
  const std::size_t n = d.t_s.size();
  fw::ModeDetector<double>::Config cfg;
  cfg.v_max = v_max;
  cfg.v_min = v_min;
  fw::ModeDetector<double> det(cfg);
  t.mode.resize(n);
  t.voltage_driven.resize(n);
  t.scored.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const fw::Mode m = det.update(d.voltage_v[i], d.current_a[i]);
    const fw::Mode raw = det.raw_mode();
    t.mode[i] = m;
    t.voltage_driven[i] = (raw == fw::Mode::cv_charge || raw == fw::Mode::cv_discharge) && raw == m;
    t.scored[i] = m == fw::Mode::cc_charge && (d.true_mode.empty() || d.true_mode[i] == fw::Mode::cc_charge);
    if (i == 0 || d.cycle[i] != d.cycle[i - 1]) t.cycles.emplace_back(i, i);
    t.cycles.back().second = i + 1;
  }
  return t;
}

fw::ModelTickResult<double> step_with_input(Cell& cell, const Track& t, std::size_t i, double input,
                                            double r_film_ohm_m2) {
  return t.voltage_driven[i] ? cell.step_voltage(input, r_film_ohm_m2, t.dt_s)
                             : cell.step_current(input, r_film_ohm_m2, t.dt_s);
}

fw::ModelTickResult<double> step(Cell& cell, const Track& t, std::size_t i, double r_film_ohm_m2) {
  const auto r = step_with_input(cell, t, i, t.input(i), r_film_ohm_m2);
  if (!r.valid)
    throw RuntimeFailure(fmt::format("{}: the reduced model failed at t_s = {} s (non-finite state)", t.data->source,
                                     t.data->t_s[i]));
  return r;
}

OutputSensitivity output_sensitivity(const Cell& cell, const Track& t, std::size_t i, double r_film_ohm_m2) {
  const double u = t.input(i);
  Cell c0 = cell, c1 = cell, c2 = cell;
  const double v0 = step_with_input(c0, t, i, u, r_film_ohm_m2).voltage_v;
  const double v_r = step_with_input(c1, t, i, u, r_film_ohm_m2 + kFilmStepOhmM2).voltage_v;
  const double v_i = step_with_input(c2, t, i, u + kCurrentStepA, r_film_ohm_m2).voltage_v;
  return {v0, (v_r - v0) / kFilmStepOhmM2, (v_i - v0) / kCurrentStepA};
}

}  // namespace bms::baselines
