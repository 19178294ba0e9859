#pragma once
// The truth DFN, minus film growth, as RCSI's main-system model: the paper's own setting
// (identical truth and main model). Same interface as the firmware's ReducedCell, so the
// firmware's BmsCore runs unchanged on top of it. Every tick in which the input or the film
// resistance changes restarts IDA from a consistent state (the film drop is algebraic).
#include <cmath>
#include <cstddef>
#include <memory>
#include <vector>

#include "bms/fw/model/reduced_cell.hpp"
#include "dfn/dfn_solver.hpp"
#include "sim/cycler.hpp"

namespace bms {

class FullDfnMainModel {
 public:
  struct State {
    double t_s = 0.0;
    std::vector<double> y;
  };

  FullDfnMainModel(const CellParameters& cell, const DfnMesh& mesh, const SolverSettings& solver,
                   const InitialConditions& ic, double temperature_k);
  ~FullDfnMainModel();
  FullDfnMainModel(const FullDfnMainModel&) = delete;
  FullDfnMainModel& operator=(const FullDfnMainModel&) = delete;

  fw::ModelTickResult<double> step_current(double current_a, double r_film_ohm_m2, double dt_s);
  fw::ModelTickResult<double> step_voltage(double voltage_v, double r_film_ohm_m2, double dt_s);
  double li_loss_ah() const;
  double li_loss_mol() const;
  // The state observer is a firmware-model feature; the paper's setting has none.
  bool resync(double, double, double, double, double) { return false; }
  // No re-synchronisation, so no inventory direction: the identifier learns no inventory.
  double inventory_probe_voltage(double, double, double, double) const { return std::nan(""); }
  State state() const;
  bool restore(const State& s);
  const SolverStats& stats() const { return solver_->stats(); }
  // Ticks whose step the DAE solver could not take (state kept, tick invalid).
  std::size_t failed_steps() const { return failed_steps_; }

 private:
  fw::ModelTickResult<double> step(ControlKind kind, double value, double r_film_ohm_m2, double dt_s);

  DfnModel model_;
  std::unique_ptr<DfnSolver> solver_;
  double inventory0_mol_ = 0.0;
  bool have_control_ = false;
  std::size_t failed_steps_ = 0;
};

}  // namespace bms
