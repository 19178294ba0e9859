#pragma once
// Integrates a DfnModel with SUNDIALS IDA (variable-order BDF) and the KLU sparse direct
// solver, with an exact sparse Jacobian from coloured forward-mode differentiation.
// Mode switches re-initialise IDA and recompute consistent algebraic variables (IDACalcIC).
#include <chrono>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "dfn/dfn_model.hpp"
#include "io/input_error.hpp"

namespace bms {

struct SolverSettings {
  double rtol = 1e-6;
  double atol = 1e-8;  // multiplied by each variable's scale (V, mol/m3, ohm.m2, ...)
  // Limits that turn a solver that cannot make progress into a RuntimeFailure instead of a
  // hang. IDA's own step limit does not apply to the one-step loop of advance_to, so they are
  // counted there. A healthy run needs a few hundred steps per CC phase and micro- to
  // milliseconds per step; every limit is orders of magnitude beyond that.
  long max_steps = 200000;     // internal steps in one advance_to / advance_exactly_to call
  double max_wall_s = 600.0;   // wall-clock seconds in one advance call
  // Crawl: crawl_window_steps consecutive steps (no restart between them) that together
  // advance the model by less than crawl_min_advance_s. After a restart IDA climbs from
  // steps of about 1 us to seconds within a few dozen steps; an integrator stuck at 1e-8 s
  // steps with Newton failures every other step (a solid diffusivity of 1e10 m2/s) trips
  // this within seconds, where the step limit alone would take minutes per output sample.
  long crawl_window_steps = 5000;
  double crawl_min_advance_s = 1e-3;
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

// Column-wise row lists of d(residual)/d(unknowns), the diagonal and the couplings a side
// reaction or temperature may add included. Structural: one evaluation of the residual with
// sparsity tracers per control kind, O(nonzeros).
std::vector<std::vector<int>> structural_jacobian_pattern(DfnModel& m, const std::vector<double>& y0);
// The same found numerically, column by column with dual numbers near y0: O(n^2) (3.35 s at
// 80/80); the structural pattern's test reference.
std::vector<std::vector<int>> probed_jacobian_pattern(DfnModel& m, const std::vector<double>& y0);

// The step or wall-clock limit of SolverSettings was reached: not a step the solver cannot
// take (a retry in smaller steps would only spend the limit again), so callers that refine
// failed steps let it through.
class SolverLimitExceeded : public RuntimeFailure {
 public:
  using RuntimeFailure::RuntimeFailure;
};

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
  void restart_after_failed_step(double tret, double tout, int flag, bool exact, int& restarts);
  Result stop_at_root();
  std::string step_failure_text(double tret, double tout, int flag, double h_last, int restarts,
                                const std::string& ida_message) const;
  void consistent_init();
  int continuation_init(double& reached);
  void update_stats();
  bool wall_limit_passed(std::chrono::steady_clock::time_point since) const;
  std::string limit_message(double tout, bool by_steps) const;
  void check_crawl(bool exact);  // throws RuntimeFailure when the last window of steps crawled

  static constexpr const char* kLimitAdvice =
      ": the cell's parameters probably make the model too stiff or inconsistent (check diffusivities, "
      "conductivities, rate constants and thicknesses against physical values), or try a looser --rtol, a "
      "coarser mesh (--points, --radial) or a smaller current";

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
