#include <algorithm>
#include <chrono>
#include <cmath>
#include <string>

#include "io/input_error.hpp"
#include "sim/cycler.hpp"
#include "sim/sample_recorder.hpp"

namespace bms {

using sim_detail::initial_state_of;
using sim_detail::Recorder;

namespace {

// The driving current of a measured profile. Measured currents jitter and toggle by an ADC
// step (0.65 mA in the About:Energy data) from sample to sample, and a CV phase decays
// smoothly over thousands of samples. Following every toggle would force IDA into tiny steps;
// holding the current piecewise constant turns the CV decay into a staircase (with a 1 %
// tolerance and a restart per stair: a +-3 mV sawtooth, the former 0.40 mV floor of
// docs/results/diagnosis.md). So:
//   - a change between two samples larger than 1 % of the largest current is a step: placed
//     half-way between the samples (the same charge as linear interpolation, what PyBaMM's
//     interpolant does), the integrator restarts there;
//   - between steps the current is continuous and piecewise linear with knots on samples:
//     each piece is as long as a line from its start can stay within `follow` of every sample
//     it spans (a feasible-slope cone, one pass). Within the cone, the end of each piece is
//     chosen to bring the charge passed since the last step back to the samples' (trapezoid)
//     charge, so the error in charge never accumulates (it would shift the end of a long
//     discharge).
// `follow` is 0.02 % of the largest current, or the jitter (90th percentile of the second
// differences away from steps) when that is larger, so noise makes no kinks.
struct CurrentProfile {
  std::vector<double> t_s, current_a;  // linear between points; a repeated time is a step
  std::vector<size_t> restart_at;      // sample indices after a step (restart half-way before them)
  std::vector<double> knot_s;          // times of the kinks, increasing
};

CurrentProfile build_current_profile(const std::vector<double>& ts, const std::vector<double>& current_a) {
  const size_t n = ts.size();
  double imax = 0.0;
  for (double i : current_a) imax = std::max(imax, std::abs(i));
  const double step = 1e-2 * imax + 1e-6;
  std::vector<double> jitter;
  for (size_t i = 1; i + 1 < n; ++i) {
    const double d1 = current_a[i] - current_a[i - 1], d2 = current_a[i + 1] - current_a[i];
    if (std::abs(d1) <= step && std::abs(d2) <= step) jitter.push_back(std::abs(d2 - d1));
  }
  double jitter90 = 0.0;
  if (!jitter.empty()) {
    const auto k = jitter.begin() + static_cast<long>(0.9 * static_cast<double>(jitter.size() - 1));
    std::nth_element(jitter.begin(), k, jitter.end());
    jitter90 = *k;
  }
  const double follow = std::max(2e-4 * imax, jitter90) + 1e-6;
  std::vector<double> charge(n, 0.0);  // trapezoid charge of the samples from the start [A s]
  for (size_t i = 1; i < n; ++i) charge[i] = charge[i - 1] + 0.5 * (current_a[i] + current_a[i - 1]) * (ts[i] - ts[i - 1]);
  CurrentProfile p;
  size_t run_start = 0;
  while (run_start < n) {
    size_t run_end = run_start;  // last sample before the next step
    while (run_end + 1 < n && std::abs(current_a[run_end + 1] - current_a[run_end]) <= step) ++run_end;
    size_t ki = run_start;  // the piece's start (a sample)
    double kv = current_a[run_start];
    double excess = 0.0;  // profile charge - sample charge since the run's start [A s]
    p.t_s.push_back(ts[ki]);
    p.current_a.push_back(kv);
    double lo = -HUGE_VAL, hi = HUGE_VAL;
    // Ends the piece at sample `last` with the slope in [lo, hi] that best repairs the charge.
    auto close = [&](size_t last) {
      const double dt = ts[last] - ts[ki];
      const double want = charge[last] - charge[ki] - excess;  // what the piece should carry
      const double slope = std::clamp(2.0 * (want - kv * dt) / (dt * dt), lo, hi);
      const double v = kv + slope * dt;
      excess += 0.5 * (kv + v) * dt - (charge[last] - charge[ki]);
      ki = last;
      kv = v;
      p.t_s.push_back(ts[last]);
      p.current_a.push_back(v);
      p.knot_s.push_back(ts[last]);
    };
    size_t last = run_start;
    for (size_t j = run_start + 1; j <= run_end; ++j) {
      const double nlo = std::max(lo, (current_a[j] - follow - kv) / (ts[j] - ts[ki]));
      const double nhi = std::min(hi, (current_a[j] + follow - kv) / (ts[j] - ts[ki]));
      if (nlo <= nhi) {
        lo = nlo;
        hi = nhi;
        last = j;
        continue;
      }
      close(last);
      lo = (current_a[j] - follow - kv) / (ts[j] - ts[ki]);
      hi = (current_a[j] + follow - kv) / (ts[j] - ts[ki]);
      last = j;
    }
    if (last > ki) close(last);
    if (run_end + 1 >= n) break;
    // The step, half-way to the next sample: hold, then jump (a repeated time in the profile).
    const double mid = 0.5 * (ts[run_end] + ts[run_end + 1]);
    p.t_s.push_back(mid);
    p.current_a.push_back(p.current_a.back());
    p.restart_at.push_back(run_end + 1);
    run_start = run_end + 1;
    p.t_s.push_back(mid);
    p.current_a.push_back(current_a[run_start]);
  }
  p.t_s.push_back(ts.back() + 1.0);  // hold the last value past the end
  p.current_a.push_back(p.current_a.back());
  return p;
}

}  // namespace

SimulationResult run_current_profile(const SimulationConfig& cfg, const std::vector<double>& t_s,
                                     const std::vector<double>& current_a, double v_stop_low,
                                     double v_stop_high, const ProgressFn& progress) {
  if (t_s.size() < 2 || t_s.size() != current_a.size()) throw InputError("current profile needs at least 2 samples");
  const auto wall0 = std::chrono::steady_clock::now();
  DfnModel model(cfg.cell, cfg.mesh, cfg.temperature_k, cfg.effects);
  DfnSolver solver(model, cfg.solver);
  // Time relative to the first sample; the profile interpolates linearly between samples and
  // treats a large change between two samples as a step (restart with consistent algebraic states).
  const double t0 = t_s.front();
  std::vector<double> ts(t_s.size());
  for (size_t i = 0; i < ts.size(); ++i) ts[i] = t_s[i] - t0;
  const CurrentProfile prof = build_current_profile(ts, current_a);
  const auto& restart_at = prof.restart_at;
  Control c;
  c.kind = ControlKind::profile;
  c.profile_t_s = &prof.t_s;
  c.profile_current_a = &prof.current_a;
  model.set_control(c);
  StopConditions stop;
  stop.voltage_below_v = v_stop_low;
  stop.voltage_above_v = v_stop_high;
  stop.min_surface_stoich = 1e-4;
  solver.start(0.0, initial_state_of(model, cfg));
  solver.switch_control(c, stop);
  Recorder rec(model, cfg.ic.r_film_ohm_m2);
  SimulationResult out;
  auto mode_of = [](double i) {
    return i > 1e-6 ? Mode::cc_discharge : (i < -1e-6 ? Mode::cc_charge : Mode::rest);
  };
  out.samples.push_back(rec.sample(t_s[0], 1, mode_of(current_a[0]), solver.y()));
  size_t next_restart = 0, next_knot = 0;
  for (size_t i = 1; i < ts.size(); ++i) {
    DfnSolver::Result res = DfnSolver::Result::reached;
    // Stop on each kink (no restart: the current is continuous), so no IDA step interpolates
    // the current through one; then the step, if any, and the sample.
    const bool restart = next_restart < restart_at.size() && restart_at[next_restart] == i;
    const double mid = 0.5 * (ts[i - 1] + ts[i]);
    while (res == DfnSolver::Result::reached && next_knot < prof.knot_s.size() && prof.knot_s[next_knot] <= ts[i] &&
           (!restart || prof.knot_s[next_knot] < mid))
      res = solver.advance_exactly_to(prof.knot_s[next_knot++]);
    if (restart) {
      if (res == DfnSolver::Result::reached) res = solver.advance_exactly_to(mid);
      if (res == DfnSolver::Result::reached) solver.restart();
      ++next_restart;
    }
    while (res == DfnSolver::Result::reached && next_knot < prof.knot_s.size() && prof.knot_s[next_knot] <= ts[i])
      res = solver.advance_exactly_to(prof.knot_s[next_knot++]);
    if (res == DfnSolver::Result::reached) res = solver.advance_to(ts[i]);
    if (res == DfnSolver::Result::stopped) {
      const StopCause& cause = solver.stop_cause();
      std::string why;
      if (cause.surface_stoich)
        why = "a particle's stoichiometry limit: " + describe(nearest_surface_limit(model, solver.y().data()));
      else if (cause.voltage_below)
        why = "the lower voltage limit " + std::to_string(v_stop_low) + " V";
      else
        why = "the upper voltage limit " + std::to_string(v_stop_high) + " V";
      out.note = "model stopped at t = " + std::to_string(solver.t() + t0) + " s at " + why +
                 ", before the end of the profile";
      break;
    }
    out.samples.push_back(rec.sample(t_s[i], 1, mode_of(current_a[i]), solver.y()));
    if (progress && i % 2000 == 0) progress(t_s[i], 1, mode_of(current_a[i]));
  }
  // A driven run is one "cycle" in the summary (contract: cycles[] is never empty).
  CycleSummary cs{};
  cs.cycle = 1;
  cs.r_film_start_ohm_m2 = out.samples.front().r_film_ohm_m2;
  cs.r_film_end_ohm_m2 = out.samples.back().r_film_ohm_m2;
  cs.growth_pct = cs.r_film_start_ohm_m2 > 0.0
                      ? 100.0 * (cs.r_film_end_ohm_m2 - cs.r_film_start_ohm_m2) / cs.r_film_start_ohm_m2
                      : 0.0;
  cs.li_loss_ah = out.samples.back().li_loss_ah - out.samples.front().li_loss_ah;
  out.cycles.push_back(cs);
  out.sim_s = solver.t();
  out.stats = solver.stats();
  out.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  return out;
}
}  // namespace bms
