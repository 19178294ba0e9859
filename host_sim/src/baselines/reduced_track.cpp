#include "baselines/reduced_track.hpp"

#include <fmt/format.h>

#include "bms/fw/estimation/mode_detector.hpp"
#include "io/input_error.hpp"

namespace bms::baselines {

Track make_track(const EstimateData& d, double v_max, double v_min) {
  Track t;
  t.data = &d;
  t.dt_s = fixed_tick_s(d);
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
