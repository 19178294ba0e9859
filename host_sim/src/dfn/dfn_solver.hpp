#pragma once
// Integrates a DfnModel with SUNDIALS IDA (variable-order BDF) and the KLU sparse direct
// solver, with an exact sparse Jacobian from coloured forward-mode differentiation.
// Mode switches re-initialise IDA and recompute consistent algebraic variables (IDACalcIC).
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "dfn/dfn_model.hpp"

namespace bms {

struct SolverSettings {
  double rtol = 1e-6;
  double atol = 1e-8;  // multiplied by each variable's scale (V, mol/m3, ohm.m2, ...)
  long max_steps = 200000;
  // When IDACalcIC finds no consistent state after a change of the input, walk the setpoint
  // there from the state's own value (DfnSolver::continuation_init). Off: fail at once.
  bool ic_continuation = true;
};

// Conditions that end the current mode; IDA locates their crossing by root-finding.
struct StopConditions {
  double voltage_below_v = -std::numeric_limits<double>::infinity();
  double voltage_above_v = std::numeric_limits<double>::infinity();
  double abs_current_below_a = -1.0;  // < 0: not watched
  double min_surface_stoich = -1.0;   // < 0: not watched (stops a driven run before a particle empties)
};

// Which stop conditions ended the last advance that returned Result::stopped (several may
// fire together).
struct StopCause {
  bool voltage_below = false, voltage_above = false, current_below = false, surface_stoich = false;
};

// The particle surface nearest a stoichiometry limit (0 or 1) in a state, for messages; node
// counts from 0 at the negative current collector (anode) or at the separator (cathode).
struct SurfaceLimit {
  bool negative = true;
  int node = -1, nodes = 0;
  double stoich = 0.0, limit = 0.0;
};
SurfaceLimit nearest_surface_limit(const DfnModel& m, const double* y);
std::string describe(const SurfaceLimit& s);

struct SolverStats {
  long steps = 0, residual_evals = 0, jacobian_evals = 0, reinits = 0, colors = 0, nonzeros = 0;
};

class DfnSolver {
 public:
  DfnSolver(DfnModel& model, const SolverSettings& settings);
  ~DfnSolver();
  DfnSolver(const DfnSolver&) = delete;
  DfnSolver& operator=(const DfnSolver&) = delete;

  // Starts at t0 from y0 (the algebraic part may be a guess).
  void start(double t0, const std::vector<double>& y0);
  // Changes the control (and stop conditions) at the current time; re-initialises.
  void switch_control(const Control& control, const StopConditions& stop);
  // Same control, but restart after a discontinuity in the input (e.g. a current step).
  void restart();

  enum class Result { reached, stopped };
  // Integrates to tout or to the first stop condition; throws RuntimeFailure on solver failure.
  Result advance_to(double tout);
  // Integrates exactly to tout without passing it (for inputs that change at tout).
  Result advance_exactly_to(double tout);

  double t() const { return t_; }
  const std::vector<double>& y() const { return y_; }
  void set_state(const std::vector<double>& y);  // for IC perturbation studies
  const SolverStats& stats() const { return stats_; }
  // Valid after advance_to / advance_exactly_to returned Result::stopped.
  const StopCause& stop_cause() const { return cause_; }
  DfnModel& model() { return model_; }

  struct Impl;

 private:
  Result advance(double tout, bool exact);
  void consistent_init();
  int continuation_init(double& reached);
  void update_stats();

  static constexpr int kMaxStepRestarts = 3;  // restarts of IDA after a step it cannot take

  DfnModel& model_;
  SolverSettings settings_;
  StopConditions stop_;
  StopCause cause_;
  double t_ = 0.0;
  std::vector<double> y_, yp_;
  SolverStats stats_, stats_base_;
  std::unique_ptr<Impl> impl_;
};

}  // namespace bms
