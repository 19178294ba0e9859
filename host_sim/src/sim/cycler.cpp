#include "sim/cycler.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>

#include "io/input_error.hpp"
#include "sim/experiment.hpp"
#include "sim/sample_recorder.hpp"

namespace bms {

using sim_detail::initial_state_of;
using sim_detail::Recorder;

bool parse_mode(const std::string& s, Mode& out) {
  for (Mode m : {Mode::rest, Mode::cc_discharge, Mode::cv_discharge, Mode::cc_charge, Mode::cv_charge}) {
    if (s == mode_name(m)) {
      out = m;
      return true;
    }
  }
  return false;
}

InitialConditions default_initial_conditions(const CellParameters& cell) {
  InitialConditions ic;
  ic.stoich_neg = cell.negative.stoich_init;
  ic.stoich_pos = cell.positive.stoich_init;
  ic.electrolyte_mol_m3 = cell.initial_electrolyte_mol_m3;
  ic.r_film_ohm_m2 = cell.side.enabled ? cell.side.initial_film_resistance_ohm_m2 : 0.0;
  return ic;
}

InitialConditions perturbed_initial_conditions(const CellParameters& cell, double ic_error_pct) {
  if (!(std::abs(ic_error_pct) < 50.0)) throw InputError("--ic-error-pct: must be within +-50");
  InitialConditions ic = default_initial_conditions(cell);
  const double s = 1.0 + ic_error_pct / 100.0;
  ic.stoich_neg *= s;
  ic.stoich_pos *= s;
  ic.electrolyte_mol_m3 *= s;
  return ic;
}

namespace {


// Stop a mode when a particle surface comes this close to 0 or 1 (the exchange current
// vanishes there and the OCP fits diverge).
constexpr double kSurfaceStoichMargin = 1e-4;

// Why a step ended at a particle's stoichiometry limit: where, which electrode, which limit.
std::string surface_limit_message(const DfnModel& model, const DfnSolver& solver, const std::string& where,
                                  const ExperimentStep& step) {
  const auto& y = solver.y();
  const SurfaceLimit s = nearest_surface_limit(model, y.data());
  const bool full = s.limit > 0.5;
  const char* electrode = s.negative ? "negative" : "positive";
  char before[96];
  if (std::isfinite(step.until_voltage_v))
    std::snprintf(before, sizeof before, "the %s voltage limit %g V", step.value > 0.0 ? "lower" : "upper",
                  step.until_voltage_v);
  else if (step.until_abs_current_a > 0.0)
    std::snprintf(before, sizeof before, "the CV end current %g A", step.until_abs_current_a);
  else
    std::snprintf(before, sizeof before, "the step's end");
  char buf[640];
  std::snprintf(buf, sizeof buf,
                "%s: at t = %.3f s the %s electrode's particle surface reached stoichiometry %.6f (limit %g, "
                "stop margin %g; node %d of %d from the %s) at %.4f V and %.4f A, before %s: the %s electrode "
                "is %s, so the protocol cannot go on (too %s cyclable lithium for this cell's window, or a "
                "current it cannot sustain)",
                where.c_str(), solver.t(), electrode, s.stoich, s.limit, kSurfaceStoichMargin, s.node + 1, s.nodes,
                s.negative ? "negative current collector" : "separator", model.terminal_voltage_v(y.data()),
                y[model.idx_current()], before, electrode, full ? "full" : "empty", full ? "much" : "little");
  return buf;
}

Control control_of(const ExperimentStep& step) { return {step.kind, step.value}; }

StopConditions stop_of(const ExperimentStep& step) {
  StopConditions stop;
  if (std::isfinite(step.until_voltage_v)) {
    if (step.value > 0.0) stop.voltage_below_v = step.until_voltage_v;
    else stop.voltage_above_v = step.until_voltage_v;
  }
  stop.abs_current_below_a = step.until_abs_current_a;
  stop.min_surface_stoich = kSurfaceStoichMargin;
  return stop;
}

// True when the step's own end is already met as it starts (IDA's root finding only sees a
// crossing, so such a step would run to its safety net).
bool already_ended(const DfnModel& model, const DfnSolver& solver, const ExperimentStep& step) {
  const double v = model.terminal_voltage_v(solver.y().data());
  const double i = solver.y()[model.idx_current()];
  if (std::isfinite(step.until_voltage_v))
    return step.value > 0.0 ? v <= step.until_voltage_v : v >= step.until_voltage_v;
  return step.until_abs_current_a > 0.0 && std::abs(i) <= step.until_abs_current_a;
}

struct StepRun {
  DfnModel& model;
  DfnSolver& solver;
  const SimulationConfig& cfg;
  const Experiment& experiment;
  SampleSink& sink;
  Recorder rec;
  const ProgressFn& progress;
  long k = 0;  // output index: t = k * dt
  bool first_sample = true;

  // Runs one step; returns false when the step ended on a voltage or current limit (and its
  // time limit did not come first), true otherwise.
  void run(int cycle, const ExperimentStep& step, CycleSummary& cs, SimulationResult& out) {
    const std::string where = "cycle " + std::to_string(cycle) + ", " + step.text;
    const double t_mode0 = solver.t();
    try {
      solver.switch_control(control_of(step), stop_of(step));
    } catch (const RuntimeFailure& e) {
      throw RuntimeFailure(where + ", starting at t = " + std::to_string(t_mode0) + " s: " + e.what());
    }
    if (first_sample) sink.on_sample(rec.sample(0.0, cycle, step.mode, solver.y()));
    first_sample = false;
    const double r_mode0 = solver.y()[model.idx_film()];
    const double t_end = t_mode0 + step.duration_s;
    bool limit_reached = already_ended(model, solver, step);
    while (!limit_reached) {
      const double tnext = static_cast<double>(k + 1) * cfg.dt_s;
      const bool last = tnext >= t_end;
      DfnSolver::Result res;
      try {
        res = last ? solver.advance_exactly_to(t_end) : solver.advance_to(tnext);
      } catch (const RuntimeFailure& e) {
        throw RuntimeFailure(where + ": " + e.what());
      }
      if (res == DfnSolver::Result::stopped) {
        limit_reached = true;
        break;
      }
      if (last && tnext > t_end) break;  // the step ends between two output times
      ++k;
      sink.on_sample(rec.sample(tnext, cycle, step.mode, solver.y()));
      if (last) break;
      if (solver.t() - t_mode0 > experiment.max_step_s)
        throw RuntimeFailure(where + ": did not end within " + std::to_string(experiment.max_step_s) +
                             " s: check the voltage limits and current");
      if (progress && k % 5000 == 0) progress(tnext, cycle, step.mode);
    }
    // A particle surface at its stoichiometry limit ends the run: the protocol cannot continue
    // physically (the electrode can take or give no more lithium at this current or voltage).
    if (limit_reached && solver.stop_cause().surface_stoich)
      throw RuntimeFailure(surface_limit_message(model, solver, where, step));
    out.phases.push_back({cycle, step.mode, t_mode0, solver.t()});
    const auto mi = static_cast<int>(step.mode);
    cs.growth_by_mode_ohm_m2[mi] += solver.y()[model.idx_film()] - r_mode0;
    cs.duration_by_mode_s[mi] += solver.t() - t_mode0;
    check_voltage_end(where, step, limit_reached);
  }

  // Any other early end of a CC step that should end at a voltage (none is expected) ends the run.
  void check_voltage_end(const std::string& where, const ExperimentStep& step, bool limit_reached) const {
    if (!limit_reached || !std::isfinite(step.until_voltage_v)) return;
    const double v = model.terminal_voltage_v(solver.y().data());
    const bool short_of_limit = step.value > 0.0 ? v > step.until_voltage_v + 1e-6 : v < step.until_voltage_v - 1e-6;
    if (short_of_limit)
      throw RuntimeFailure(where + ": ended at t = " + std::to_string(solver.t()) + " s at " + std::to_string(v) +
                           " V, before the voltage limit");
  }
};

}  // namespace

SimulationResult run_experiment(const SimulationConfig& cfg, const Experiment& experiment, SampleSink& sink,
                                const ProgressFn& progress) {
  if (!(cfg.dt_s > 0.0)) throw InputError("--dt must be positive");
  const auto wall0 = std::chrono::steady_clock::now();
  DfnModel model(cfg.cell, cfg.mesh, cfg.temperature_k, cfg.effects);
  DfnSolver solver(model, cfg.solver);
  Control rest_control{ControlKind::current, 0.0};
  model.set_control(rest_control);
  solver.start(0.0, initial_state_of(model, cfg));
  StepRun steps{model, solver, cfg, experiment, sink, Recorder(model, cfg.ic.r_film_ohm_m2), progress};

  SimulationResult out;
  for (int cycle = 1; cycle <= experiment.cycles; ++cycle) {
    CycleSummary cs{};
    cs.cycle = cycle;
    cs.r_film_start_ohm_m2 = solver.y()[model.idx_film()];
    for (const ExperimentStep& step : experiment.steps) steps.run(cycle, step, cs, out);
    cs.r_film_end_ohm_m2 = solver.y()[model.idx_film()];
    cs.growth_pct = cs.r_film_start_ohm_m2 > 0.0
                        ? 100.0 * (cs.r_film_end_ohm_m2 - cs.r_film_start_ohm_m2) / cs.r_film_start_ohm_m2
                        : 0.0;
    cs.li_loss_ah = model.lithium_loss_mol(cs.r_film_end_ohm_m2, cs.r_film_start_ohm_m2) * kFaradayC_mol / 3600.0;
    out.cycles.push_back(cs);
    sink.on_cycle(cs);
  }
  out.sim_s = solver.t();
  out.stats = solver.stats();
  out.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  return out;
}

SimulationResult run_cccv(const SimulationConfig& cfg, const CccvProtocol& protocol, const ProgressFn& progress) {
  const Experiment experiment = cccv_experiment(protocol);
  std::vector<SampleRecord> samples;
  SampleCollector sink(samples);
  SimulationResult out = run_experiment(cfg, experiment, sink, progress);
  out.samples = std::move(samples);
  return out;
}

}  // namespace bms
