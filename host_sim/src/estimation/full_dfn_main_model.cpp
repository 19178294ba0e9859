#include "estimation/full_dfn_main_model.hpp"

#include <cmath>

#include "io/input_error.hpp"

namespace bms {

FullDfnMainModel::FullDfnMainModel(const CellParameters& cell, const DfnMesh& mesh, const SolverSettings& solver,
                                   const InitialConditions& ic, double temperature_k)
    : model_(cell, mesh, temperature_k) {
  model_.set_film_frozen(true);
  model_.set_control({ControlKind::current, 0.0});
  solver_ = std::make_unique<DfnSolver>(model_, solver);
  solver_->start(0.0, model_.initial_state(ic.stoich_neg, ic.stoich_pos, ic.electrolyte_mol_m3, ic.r_film_ohm_m2));
  inventory0_mol_ = model_.lithium_inventory_mol(solver_->y().data());
}

FullDfnMainModel::~FullDfnMainModel() = default;

fw::ModelTickResult<double> FullDfnMainModel::step_current(double current_a, double r_film, double dt_s) {
  return step(ControlKind::current, current_a, r_film, dt_s);
}

fw::ModelTickResult<double> FullDfnMainModel::step_voltage(double voltage_v, double r_film, double dt_s) {
  return step(ControlKind::voltage, voltage_v, r_film, dt_s);
}

fw::ModelTickResult<double> FullDfnMainModel::step(ControlKind kind, double value, double r_film, double dt_s) {
  const Control before = model_.control();
  const bool had_control = have_control_;
  const double t0 = solver_->t();
  const std::vector<double> y0 = solver_->y();  // kept to return to if the step fails
  try {
    const bool control_changed = !have_control_ || before.kind != kind || before.value != value;
    const bool film_changed = y0[model_.idx_film()] != r_film;
    if (control_changed || film_changed) {
      // One consistent re-initialisation for both changes.
      model_.set_control({kind, value});
      std::vector<double> y = y0;
      y[model_.idx_film()] = r_film;
      solver_->set_state(y);
      have_control_ = true;
    }
    solver_->advance_to(t0 + dt_s);
  } catch (const RuntimeFailure&) {
    // A state the DAE cannot continue from with this input (e.g. a model started 1 % off that
    // cannot deliver the measured current at the end of a discharge): like the reduced model's
    // failed Newton step, the tick is invalid and the state stays where it was, so the core
    // holds its estimate and flags kModelInvalid instead of the whole run aborting.
    model_.set_control(before);
    solver_->start(t0, y0);
    have_control_ = had_control;
    fw::ModelTickResult<double> bad{};
    bad.voltage_v = bad.current_a = bad.j_side_a_m3 = bad.markov_v_per_ohm_m2 = std::nan("");
    bad.valid = false;
    bad.converged = false;
    ++failed_steps_;
    return bad;
  }
  const double* ys = solver_->y().data();
  fw::ModelTickResult<double> r{};
  r.voltage_v = model_.terminal_voltage_v(ys);
  r.current_a = ys[model_.idx_current()];
  r.j_side_a_m3 = model_.mean_side_current_a_m2(ys) * model_.cell().negative.surface_area_per_volume_m();
  const auto& neg = model_.cell().negative;
  r.markov_v_per_ohm_m2 = -r.current_a / (model_.cell().electrode_area_m2 * neg.surface_area_per_volume_m() * neg.thickness_m);
  r.newton_iterations = 0;
  r.converged = true;
  r.valid = std::isfinite(r.voltage_v) && std::isfinite(r.j_side_a_m3);
  return r;
}

double FullDfnMainModel::li_loss_ah() const {
  return (inventory0_mol_ - model_.lithium_inventory_mol(solver_->y().data())) * kFaradayC_mol / 3600.0;
}

double FullDfnMainModel::li_loss_mol() const {
  return inventory0_mol_ - model_.lithium_inventory_mol(solver_->y().data());
}

FullDfnMainModel::State FullDfnMainModel::state() const { return {solver_->t(), solver_->y()}; }

bool FullDfnMainModel::restore(const State& s) {
  if (static_cast<int>(s.y.size()) != model_.size()) return false;
  for (double v : s.y)
    if (!std::isfinite(v)) return false;
  solver_->start(s.t_s, s.y);
  have_control_ = false;
  return true;
}

}  // namespace bms
