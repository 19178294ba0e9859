#pragma once
// Checks of the truth model against physics (conservation), itself (mesh convergence), the
// paper's reported observables, and measurements (About:Energy discharges vs PyBaMM).
// Used by `bmssim validate` (numbers for docs/results/truth-model.md) and by the tests.
#include <string>
#include <vector>

#include "sim/cycler.hpp"

namespace bms {

struct ConservationReport {
  // Side reaction off:
  double inventory_drift_rel_per_cycle = 0.0;  // |Δ(solid + electrolyte Li)| / Li, worst cycle
  double max_stoich_sum_error = 0.0;           // max |θn + θp - 1| over the run (paper cell)
  // θn + θp = 1 holds only as far as the two electrodes' capacities agree (0.025 % apart in
  // the paper set); the exact invariant is C_n θn + C_p θp = const.
  double max_solid_lithium_drift_rel = 0.0;
  double throughput_vs_cathode_rel = 0.0;      // |∫I dt - F ΔN_cathode| / capacity
  // Side reaction on:
  double li_loss_mol = 0.0;                    // drop of the inventory over the run
  double li_side_current_mol = 0.0;            // ∫ A L_n J_s dt / F (trapezoid on the samples)
  double li_loss_rel_error = 0.0;
  double charge_state_vs_trapezoid_rel = 0.0;  // integrator's ∫I dt vs trapezoid of the samples
};

ConservationReport check_conservation(const CellParameters& cell, int cycles);

// Voltage difference to the doubled mesh in the CC phases of one CCCV cycle, compared at the
// same time since each phase began (the switching times themselves shift slightly with the
// mesh). `interior` excludes the first and last 30 s of each phase, where the voltage moves
// by up to 100 mV/s (leaving CV discharge at 2.0 V, and the end-of-discharge knee).
struct ConvergenceRow {
  int points = 0, radial = 0, unknowns = 0;
  double max_diff_mv = 0.0, rms_diff_mv = 0.0;                    // whole CC phases
  double interior_max_diff_mv = 0.0, interior_rms_diff_mv = 0.0;  // without the 30 s edges
  double max_phase_end_shift_s = 0.0;  // worst change of a CC phase's duration
  double wall_s = 0.0;
};
std::vector<ConvergenceRow> check_mesh_convergence(const CellParameters& cell, const std::vector<int>& points);

struct PaperObservables {
  std::vector<double> growth_pct_per_cycle;
  double growth_share_cc_charge = 0.0, growth_share_cv_charge = 0.0, growth_share_discharge = 0.0;
  std::vector<double> dv_successive_cc_charge_mv;  // median |V_k+1 - V_k| in CC charge, same time in phase
  double dv_current_2p495_mv = 0.0;        // median |V(2.50 A) - V(2.495 A)| over the first CC charge
  double dv_current_2p495_start_mv = 0.0;  // the same over its first 60 s (before the SOC drifts apart)
  double film_drop_growth_mv = 0.0;  // dR per cycle x CC pore-wall current (expected dV per cycle)
  double theta_m1 = 1.0, theta_n1 = 0.0;  // true subsystem at T = 0.2 s, J_s in A/m3
};
PaperObservables paper_observables(int cycles);

struct MeasuredCase {
  std::string name, file;
  double pybamm_rmse_mv = 0.0, rmse_mv = 0.0, max_abs_mv = 0.0, wall_s = 0.0;
  size_t samples = 0;
  std::string note;
};
std::vector<MeasuredCase> compare_aboutenergy(const DfnMesh& mesh);

// Voltage RMSE between a simulation and measured (t, V), over the simulated samples.
double rmse_against(const SimulationResult& r, const std::vector<double>& t_s, const std::vector<double>& v);

}  // namespace bms
