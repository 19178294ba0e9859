#include "sim/cycler.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <string>

#include "io/input_error.hpp"
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

// Why a mode ended at a particle's stoichiometry limit: where, which electrode, which limit.
std::string surface_limit_message(const DfnModel& model, const DfnSolver& solver, const std::string& where, Mode mode,
                                  const CccvProtocol& protocol) {
  const auto& y = solver.y();
  const SurfaceLimit s = nearest_surface_limit(model, y.data());
  const bool full = s.limit > 0.5;
  const char* electrode = s.negative ? "negative" : "positive";
  char before[96];
  if (mode == Mode::cc_discharge) std::snprintf(before, sizeof before, "the lower voltage limit %g V", protocol.v_min);
  else if (mode == Mode::cc_charge) std::snprintf(before, sizeof before, "the upper voltage limit %g V", protocol.v_max);
  else std::snprintf(before, sizeof before, "the CV end current %g A", protocol.cv_end_current_a);
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


}  // namespace

SimulationResult run_cccv(const SimulationConfig& cfg, const CccvProtocol& protocol, const ProgressFn& progress) {
  if (!(protocol.v_min < protocol.v_max))
    throw InputError("voltage limits inverted: lower " + std::to_string(protocol.v_min) +
                     " V must be below upper " + std::to_string(protocol.v_max) + " V");
  if (!(protocol.current_a > 0.0)) throw InputError("--current-a must be positive (a magnitude)");
  if (!(cfg.dt_s > 0.0)) throw InputError("--dt must be positive");
  const auto wall0 = std::chrono::steady_clock::now();
  DfnModel model(cfg.cell, cfg.mesh, cfg.temperature_k, cfg.effects);
  DfnSolver solver(model, cfg.solver);
  Control rest_control{ControlKind::current, 0.0};
  model.set_control(rest_control);
  solver.start(0.0, initial_state_of(model, cfg));
  Recorder rec(model, cfg.ic.r_film_ohm_m2);

  SimulationResult out;
  long k = 0;  // output index: t = k * dt
  const Mode sequence[4] = {Mode::cc_discharge, Mode::cv_discharge, Mode::cc_charge, Mode::cv_charge};
  for (int cycle = 1; cycle <= protocol.cycles; ++cycle) {
    CycleSummary cs{};
    cs.cycle = cycle;
    cs.r_film_start_ohm_m2 = solver.y()[model.idx_film()];
    for (Mode mode : sequence) {
      Control c;
      StopConditions stop;
      switch (mode) {
        case Mode::cc_discharge:
          c = {ControlKind::current, protocol.current_a};
          stop.voltage_below_v = protocol.v_min;
          break;
        case Mode::cv_discharge:
          c = {ControlKind::voltage, protocol.v_min};
          stop.abs_current_below_a = protocol.cv_end_current_a;
          break;
        case Mode::cc_charge:
          c = {ControlKind::current, -protocol.current_a};
          stop.voltage_above_v = protocol.v_max;
          break;
        case Mode::cv_charge:
          c = {ControlKind::voltage, protocol.v_max};
          stop.abs_current_below_a = protocol.cv_end_current_a;
          break;
        case Mode::rest:
        case Mode::unknown: break;
      }
      stop.min_surface_stoich = kSurfaceStoichMargin;
      const std::string where = "cycle " + std::to_string(cycle) + ", " + mode_name(mode);
      const double t_mode0 = solver.t();
      try {
        solver.switch_control(c, stop);
      } catch (const RuntimeFailure& e) {
        throw RuntimeFailure(where + ", starting at t = " + std::to_string(t_mode0) + " s: " + e.what());
      }
      if (out.samples.empty()) out.samples.push_back(rec.sample(0.0, cycle, mode, solver.y()));
      const double r_mode0 = solver.y()[model.idx_film()];
      while (true) {
        const double tnext = static_cast<double>(k + 1) * cfg.dt_s;
        DfnSolver::Result res;
        try {
          res = solver.advance_to(tnext);
        } catch (const RuntimeFailure& e) {
          throw RuntimeFailure(where + ": " + e.what());
        }
        if (res == DfnSolver::Result::stopped) break;
        ++k;
        out.samples.push_back(rec.sample(tnext, cycle, mode, solver.y()));
        if (solver.t() - t_mode0 > protocol.max_mode_s)
          throw RuntimeFailure(where + ": did not end within " +
                               std::to_string(protocol.max_mode_s) + " s: check the voltage limits and current");
        if (progress && k % 5000 == 0) progress(tnext, cycle, mode);
      }
      // A particle surface at its stoichiometry limit ends the run: the protocol cannot continue
      // physically (the electrode can take or give no more lithium at this current or voltage).
      if (solver.stop_cause().surface_stoich)
        throw RuntimeFailure(surface_limit_message(model, solver, where, mode, protocol));
      out.phases.push_back({cycle, mode, t_mode0, solver.t()});
      const auto mi = static_cast<int>(mode);
      cs.growth_by_mode_ohm_m2[mi] += solver.y()[model.idx_film()] - r_mode0;
      cs.duration_by_mode_s[mi] += solver.t() - t_mode0;
      // Any other early end of a CC phase (none is expected) also ends the run.
      const double v = model.terminal_voltage_v(solver.y().data());
      if ((mode == Mode::cc_discharge && v > protocol.v_min + 1e-6) ||
          (mode == Mode::cc_charge && v < protocol.v_max - 1e-6))
        throw RuntimeFailure(where + ": ended at t = " + std::to_string(solver.t()) + " s at " + std::to_string(v) +
                             " V, before the voltage limit");
    }
    cs.r_film_end_ohm_m2 = solver.y()[model.idx_film()];
    cs.growth_pct = cs.r_film_start_ohm_m2 > 0.0
                        ? 100.0 * (cs.r_film_end_ohm_m2 - cs.r_film_start_ohm_m2) / cs.r_film_start_ohm_m2
                        : 0.0;
    cs.li_loss_ah = model.lithium_loss_mol(cs.r_film_end_ohm_m2, cs.r_film_start_ohm_m2) * kFaraday_c_mol / 3600.0;
    out.cycles.push_back(cs);
  }
  out.sim_s = solver.t();
  out.stats = solver.stats();
  out.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  return out;
}

}  // namespace bms
