#pragma once
// A constant-current discharge of the About:Energy cell (side reaction off) on a coarse mesh,
// for the tests of the cathode's stoichiometry-dependent effects (diffusivity profile,
// resistive reactant).
#include <cmath>
#include <vector>

#include "dfn/dfn_solver.hpp"
#include "sim/cell_catalog.hpp"
#include "sim/cycler.hpp"

namespace bms::ae_discharge {

inline const DfnMesh kCoarse{6, 3, 6, 8};

inline CellParameters ae_cell() {
  CellParameters c = load_cell("aboutenergy");
  c.side.enabled = false;
  return c;
}

// The discharge at current_a from full to stop_v: (end s, voltage every 60 s, inventory drift).
struct Discharge {
  double end_s = 0.0;
  std::vector<double> v;
  double inventory_drift = 0.0;
};

inline Discharge discharge(const CellParameters& cell, const ModelEffects& effects, double current_a, double stop_v,
                           double temperature_k = 298.15) {
  DfnModel m(cell, kCoarse, temperature_k, effects);
  DfnSolver solver(m, SolverSettings{});
  m.set_control({ControlKind::current, 0.0});
  const auto ic = default_initial_conditions(cell);
  solver.start(0.0, m.initial_state(ic.stoich_neg, ic.stoich_pos, ic.electrolyte_mol_m3, 0.0));
  const double inventory0 = m.lithium_inventory_mol(solver.y().data());
  StopConditions stop;
  stop.voltage_below_v = stop_v;
  solver.switch_control({ControlKind::current, current_a}, stop);
  Discharge d;
  for (double t = 60.0; t < 20000.0; t += 60.0) {
    const auto r = solver.advance_to(t);
    d.v.push_back(m.terminal_voltage_v(solver.y().data()));
    if (r == DfnSolver::Result::stopped) break;
  }
  d.end_s = solver.t();
  d.inventory_drift = std::abs(m.lithium_inventory_mol(solver.y().data()) - inventory0) / inventory0;
  return d;
}

}  // namespace bms::ae_discharge
