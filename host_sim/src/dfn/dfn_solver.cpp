#include "dfn/dfn_solver.hpp"

#include <ida/ida.h>
#include <nvector/nvector_serial.h>
#include <sundials/sundials_context.h>
#include <sunlinsol/sunlinsol_klu.h>
#include <sunmatrix/sunmatrix_sparse.h>

#include <algorithm>
#include <chrono>
#include <map>
#include <mutex>
#include <tuple>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <random>
#include <string>

#include "dfn/fast_serial_ops.hpp"
#include "dfn/multi_dual.hpp"
#include "dfn/sparsity_tracer.hpp"
#include "io/child_process.hpp"
#include "io/input_error.hpp"

namespace bms {

using fw::Dual;

struct DfnSolver::Impl {
  SUNContext ctx = nullptr;
  void* ida = nullptr;
  N_Vector y = nullptr, yp = nullptr, atol = nullptr, id = nullptr, tmp = nullptr;
  double tn = 0.0;  // time of IDA's internal solution (>= the caller's time)
  // Crawl detection: IDA's step count and time at the start of the current window.
  long window_steps0 = 0;
  double window_t0 = 0.0;
  bool root_pending = false;  // a stop condition was found after the time last asked for
  double root_t = 0.0;
  int roots[4] = {0, 0, 0, 0};  // IDAGetRootInfo of the pending root
  SUNMatrix jac = nullptr;
  SUNLinearSolver ls = nullptr;
  struct Structure {
    std::vector<sunindextype> colptr, rowind;
    std::vector<int> color;
    int ncolors = 0;
  };
  // Compressed-column pattern of dF/dy + cj dF/dy', and the colour of every column.
  std::vector<sunindextype> colptr, rowind;
  std::vector<int> color;
  int ncolors = 0;
  std::vector<JacobianDual> yd, gd;
  std::vector<std::pair<int, double>> film_row;
  DfnSolver* owner = nullptr;
  const StopConditions* stop = nullptr;

  // Frees the integrator (not the context): start() may be called again (a caller returning
  // to a saved state after a failure).
  void release() {
    if (ida) IDAFree(&ida);
    if (ls) SUNLinSolFree(ls);
    if (jac) SUNMatDestroy(jac);
    for (N_Vector* v : {&y, &yp, &atol, &id, &tmp}) {
      if (*v) N_VDestroy(*v);
      *v = nullptr;
    }
    ida = nullptr;
    ls = nullptr;
    jac = nullptr;
  }
  ~Impl() {
    release();
    if (ctx) SUNContext_Free(&ctx);
  }
};

namespace {

int residual_fn(realtype t, N_Vector y, N_Vector yp, N_Vector r, void* user) {
  auto* impl = static_cast<DfnSolver::Impl*>(user);
  DfnModel& m = impl->owner->model();
  const double* yv = N_VGetArrayPointer(y);
  const double* ypv = N_VGetArrayPointer(yp);
  double* rv = N_VGetArrayPointer(r);
  m.eval_g(t, yv, rv);
  const auto& mass = m.mass();
  const int n = m.size();
  for (int i = 0; i < n; ++i) {
    rv[i] = mass[i] * ypv[i] - rv[i];
    if (!std::isfinite(rv[i])) return 1;  // recoverable: IDA retries with a smaller step
  }
  return 0;
}

int jacobian_fn(realtype t, realtype cj, N_Vector y, N_Vector, N_Vector, SUNMatrix jac, void* user,
                N_Vector, N_Vector, N_Vector) {
  auto* impl = static_cast<DfnSolver::Impl*>(user);
  DfnModel& m = impl->owner->model();
  const int n = m.size();
  const double* yv = N_VGetArrayPointer(y);
  const auto& mass = m.mass();
  double* data = SUNSparseMatrix_Data(jac);
  sunindextype* cp = SUNSparseMatrix_IndexPointers(jac);
  sunindextype* ri = SUNSparseMatrix_IndexValues(jac);
  std::copy(impl->colptr.begin(), impl->colptr.end(), cp);
  std::copy(impl->rowind.begin(), impl->rowind.end(), ri);
  // kJacobianLanes colours per residual evaluation.
  for (int c0 = 0; c0 < impl->ncolors; c0 += kJacobianLanes) {
    for (int i = 0; i < n; ++i) {
      impl->yd[i] = JacobianDual(yv[i]);
      const int lane = impl->color[i] - c0;
      if (lane >= 0 && lane < kJacobianLanes) impl->yd[i].d[lane] = 1.0;
    }
    m.eval_g(t, impl->yd.data(), impl->gd.data());
    for (int col = 0; col < n; ++col) {
      const int lane = impl->color[col] - c0;
      if (lane < 0 || lane >= kJacobianLanes) continue;
      for (auto k = impl->colptr[col]; k < impl->colptr[col + 1]; ++k) {
        const auto row = impl->rowind[k];
        data[k] = -impl->gd[row].d[lane] + (row == col ? cj * mass[row] : 0.0);
      }
    }
  }
  // The film row couples every anode node; it was left out of the colouring and is exact here.
  m.film_row_jacobian(yv, impl->film_row);
  const int frow = m.film_row();
  for (const auto& [col, dg] : impl->film_row) {
    for (auto k = impl->colptr[col]; k < impl->colptr[col + 1]; ++k) {
      if (impl->rowind[k] == frow) {
        data[k] = -dg + (frow == col ? cj * mass[frow] : 0.0);
        break;
      }
    }
  }
  for (auto k = 0; k < impl->colptr[n]; ++k)
    if (!std::isfinite(data[k])) return 1;
  return 0;
}

int root_fn(realtype, N_Vector y, N_Vector, realtype* gout, void* user) {
  auto* impl = static_cast<DfnSolver::Impl*>(user);
  const DfnModel& m = impl->owner->model();
  const StopConditions& st = *impl->stop;
  const double* yv = N_VGetArrayPointer(y);
  const double v = m.terminal_voltage_v(yv);
  const double i = yv[m.idx_current()];
  gout[0] = std::isfinite(st.voltage_below_v) ? v - st.voltage_below_v : 1.0;
  gout[1] = std::isfinite(st.voltage_above_v) ? v - st.voltage_above_v : -1.0;
  gout[2] = st.abs_current_below_a >= 0.0 ? std::abs(i) - st.abs_current_below_a : 1.0;
  if (st.min_surface_stoich >= 0.0) {
    double margin = 1.0;
    for (int e = 0; e < m.n_electrode_nodes(); ++e) {
      const double x = m.surface_stoich(yv, e);
      margin = std::min(margin, std::min(x, 1.0 - x));
    }
    gout[3] = margin - st.min_surface_stoich;
  } else {
    gout[3] = 1.0;
  }
  return 0;
}

// IDA re-initialises its linear solver at every IDAReInit (each change of control and each
// restart), and KLU's initialisation throws away its symbolic analysis (ordering) and pivots,
// so the next setup analyses and factors from scratch. The matrix pattern never changes: keep
// both and let the setup refactor; it still factors afresh when the refactored matrix is
// ill-conditioned (SUNLinSolSetup_KLU's reciprocal condition check).
int klu_initialize_once(SUNLinearSolver ls) {
  if (SUNLinSol_KLUGetNumeric(ls) == nullptr) return SUNLinSolInitialize_KLU(ls);
  return SUNLS_SUCCESS;
}

// That condition check is KLU's cheap estimate (the ratio of U's smallest to largest diagonal),
// and it can pass a refactorisation whose stale pivot order is useless for the new matrix: at a
// switch from current to voltage control (an LCO cell at 80 volumes entering its CV charge) the
// solution came back NaN and IDACalcIC failed for good. A non-finite solution therefore gets one
// fresh factorisation with its own pivoting, and the solve is repeated; a solve that was finite
// is untouched, so runs that never met this are unchanged bit for bit.
int klu_solve_refactor_on_nan(SUNLinearSolver ls, SUNMatrix a, N_Vector x, N_Vector b, realtype tol) {
  int flag = SUNLinSolSolve_KLU(ls, a, x, b, tol);
  if (flag != SUNLS_SUCCESS) return flag;
  const double* xv = N_VGetArrayPointer(x);
  const auto n = N_VGetLength(x);
  if (std::all_of(xv, xv + n, [](double v) { return std::isfinite(v); })) return flag;
  flag = SUNLinSolInitialize_KLU(ls);
  if (flag == SUNLS_SUCCESS) flag = SUNLinSolSetup_KLU(ls, a);
  if (flag == SUNLS_SUCCESS) flag = SUNLinSolSolve_KLU(ls, a, x, b, tol);
  return flag;
}

// IDA's own error text, kept for the exception instead of IDA printing it to stderr: a caller
// that recovers from a failed step (the estimator's full main model) must not flood the
// terminal, and one that does not gets the text in its error message.
thread_local std::string last_ida_message;

void keep_ida_message(int /*code*/, const char* /*module*/, const char* function, char* msg, void* /*data*/) {
  last_ida_message = std::string(function) + ": " + msg;
}

// IDA's name of a return flag (IDAGetReturnFlagName returns a malloc'ed string).
std::string flag_name(int flag) {
  char* name = IDAGetReturnFlagName(flag);
  std::string out = name ? name : "?";
  std::free(name);
  return out;
}

void check(int flag, const char* what) {
  if (flag < 0) {
    std::string text = std::string("IDA: ") + what + " failed (flag " + std::to_string(flag) + ")";
    if (!last_ida_message.empty()) text += ": " + last_ida_message;
    last_ida_message.clear();
    throw RuntimeFailure(text);
  }
}

}  // namespace

SurfaceLimit nearest_surface_limit(const DfnModel& m, const double* y) {
  SurfaceLimit best;
  double margin = HUGE_VAL;
  for (int e = 0; e < m.n_electrode_nodes(); ++e) {
    const double x = m.surface_stoich(y, e);
    for (const double limit : {0.0, 1.0}) {
      if (std::abs(x - limit) < margin) {
        margin = std::abs(x - limit);
        best.negative = e < m.mesh().n_neg;
        best.node = best.negative ? e : e - m.mesh().n_neg;
        best.nodes = best.negative ? m.mesh().n_neg : m.mesh().n_pos;
        best.stoich = x;
        best.limit = limit;
      }
    }
  }
  return best;
}

std::string describe(const SurfaceLimit& s) {
  if (s.node < 0) return "no particle";
  // Nodes count from the negative current collector; the cathode's first node is next to the separator.
  char buf[256];
  std::snprintf(buf, sizeof buf, "nearest particle surface to a limit: %s electrode, node %d of %d, stoichiometry %.6f (limit %g)",
                s.negative ? "negative" : "positive", s.node + 1, s.nodes, s.stoich, s.limit);
  return buf;
}

}  // namespace bms

namespace bms {
namespace {

// Couplings every pattern carries, and the diagonal (IDA adds cj M on it), sorted.
void add_fixed_couplings(const DfnModel& m, std::vector<std::vector<int>>& cols) {
  const int n = m.size();
  for (int col = 0; col < n; ++col) cols[col].push_back(col);
  // The film row is always structurally coupled to every anode potential and reaction current.
  for (int e = 0; e < m.mesh().n_neg; ++e)
    for (int col : {m.idx_phis(e), m.idx_phie(e), m.idx_j(e)}) cols[col].push_back(m.film_row());
  // Temperature reaches every row through F/RT and the Arrhenius factors; a cell with a zero
  // activation energy or no entropic data would hide some of them from the probe, and the
  // pattern is shared between cells, so the column is taken as dense.
  if (m.idx_temperature() >= 0)
    for (int row = 0; row < n; ++row) cols[m.idx_temperature()].push_back(row);
  for (auto& c : cols) {
    std::sort(c.begin(), c.end());
    c.erase(std::unique(c.begin(), c.end()), c.end());
  }
}

}  // namespace

// Numerical pattern of dg/dy: union over a few random states near y0 and both control kinds,
// found column by column with dual numbers. O(n^2): kept as the reference of the structural
// pattern's test.
std::vector<std::vector<int>> probed_jacobian_pattern(DfnModel& m, const std::vector<double>& y0) {
  const int n = m.size();
  std::vector<std::vector<int>> cols(n);
  std::vector<Dual<double>> yd(n), gd(n);
  std::mt19937_64 rng(12345);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  const Control saved = m.control();
  const bool saved_frozen = false;
  for (int trial = 0; trial < 2; ++trial) {
    Control c;
    c.kind = trial == 0 ? ControlKind::current : ControlKind::voltage;
    c.value = trial == 0 ? 1.0 : 3.3;
    m.set_control(c);
    std::vector<double> y = y0;
    // Small currents keep the trial state physical (a steep OCP can overflow otherwise).
    for (int e = 0; e < m.n_electrode_nodes(); ++e) y[m.idx_j(e)] = 1e-3 * (1.0 + 0.1 * u(rng));
    // Further particle populations (particle-size effect): a zero j would hide the film drop
    // j R_film from the pattern. Fixed values keep the generator's sequence, and so the plain
    // model's pattern, unchanged.
    for (int e = 0; e < m.n_electrode_nodes(); ++e)
      for (int p = 1; p < m.n_populations(e); ++p) y[m.idx_j_pop(e, p)] = 1e-3 * (1.0 + 0.01 * p);
    y[m.idx_current()] = 1e-2 * (1.0 + 0.1 * u(rng));
    for (int i = 0; i < n; ++i) y[i] *= 1.0 + 1e-3 * u(rng);
    // The heat rows multiply potential differences (i_s x grad phi_s), which vanish in a
    // uniform initial state (phi_s = 0 across the anode) and would hide their columns.
    if (m.idx_temperature() >= 0)
      for (int i = 0; i < n; ++i) y[i] += 1e-6 * u(rng);
    for (int col = 0; col < n; ++col) {
      for (int i = 0; i < n; ++i) yd[i] = Dual<double>{y[i], i == col ? 1.0 : 0.0};
      m.eval_g(0.0, yd.data(), gd.data());
      for (int row = 0; row < n; ++row)
        if ((std::isfinite(gd[row].d) && gd[row].d != 0.0) || row == col) cols[col].push_back(row);
    }
  }
  (void)saved_frozen;
  m.set_control(saved);
  add_fixed_couplings(m, cols);
  return cols;
}


// Structural pattern of dg/dy: one residual evaluation per control kind with sparsity tracers.
std::vector<std::vector<int>> structural_jacobian_pattern(DfnModel& m, const std::vector<double>& y0) {
  const int n = m.size();
  std::vector<std::vector<int>> cols(n);
  std::vector<SparsityTracer> yt(n), gt(n);
  const Control saved = m.control();
  for (const ControlKind kind : {ControlKind::current, ControlKind::voltage}) {
    Control c;
    c.kind = kind;
    c.value = kind == ControlKind::current ? 1.0 : 3.3;
    m.set_control(c);
    for (int i = 0; i < n; ++i) yt[i] = SparsityTracer(y0[i], {i});
    m.eval_g(0.0, yt.data(), gt.data());
    for (int row = 0; row < n; ++row)
      for (int col : gt[row].deps) cols[col].push_back(row);
  }
  m.set_control(saved);
  add_fixed_couplings(m, cols);
  return cols;
}

namespace {

// Compressed columns of the pattern and a greedy distance-2 colouring of its columns, ignoring
// the dense film row (its entries are computed analytically).
DfnSolver::Impl::Structure build_structure(const DfnModel& m, const std::vector<std::vector<int>>& cols) {
  const int n = m.size();
  DfnSolver::Impl::Structure st;
  st.colptr.assign(n + 1, 0);
  for (int c = 0; c < n; ++c) {
    st.colptr[c + 1] = st.colptr[c] + static_cast<sunindextype>(cols[c].size());
    for (int r : cols[c]) st.rowind.push_back(r);
  }
  std::vector<std::vector<int>> rows(n);
  for (int c = 0; c < n; ++c)
    for (int r : cols[c])
      if (r != m.film_row()) rows[r].push_back(c);
  st.color.assign(n, -1);
  std::vector<int> forbidden(n + 1, -1);
  for (int c = 0; c < n; ++c) {
    for (int r : cols[c]) {
      if (r == m.film_row()) continue;
      for (int other : rows[r])
        if (st.color[other] >= 0) forbidden[st.color[other]] = c;
    }
    int k = 0;
    while (forbidden[k] == c) ++k;
    st.color[c] = k;
    st.ncolors = std::max(st.ncolors, k + 1);
  }
  return st;
}

// The pattern depends only on the mesh and on which terms are present, not on the cell's
// values: pattern and colouring are built once per process for each such structure (a solver
// built many times, as in studies and benchmarks, pays for them once).
const DfnSolver::Impl::Structure& jacobian_structure(DfnModel& m, const std::vector<double>& y0) {
  static std::mutex mutex;
  using Key = std::tuple<int, int, int, int, bool, bool, bool, bool, int, int, bool>;
  static std::map<Key, std::unique_ptr<const DfnSolver::Impl::Structure>> cache;
  const auto& mesh = m.mesh();
  const Key key = std::make_tuple(mesh.n_neg, mesh.n_sep, mesh.n_pos, mesh.n_r, m.side_reaction_enabled(),
                                  m.idx_hysteresis() >= 0, m.idx_temperature() >= 0, m.temperature_dependent(),
                                  m.size(), m.n_populations(0),  // tells the particle populations apart
                                  m.effects().resistive_reactant_on());  // a cathode reaction row reads every shell
  {
    std::lock_guard<std::mutex> lock(mutex);
    if (auto it = cache.find(key); it != cache.end()) return *it->second;
  }
  auto st = std::make_unique<const DfnSolver::Impl::Structure>(build_structure(m, structural_jacobian_pattern(m, y0)));
  std::lock_guard<std::mutex> lock(mutex);
  return *cache.emplace(key, std::move(st)).first->second;  // a concurrent first build keeps the earlier one
}

}  // namespace

DfnSolver::DfnSolver(DfnModel& model, const SolverSettings& settings)
    : model_(model), settings_(settings), impl_(std::make_unique<Impl>()) {
  impl_->owner = this;
  impl_->stop = &stop_;
  check(SUNContext_Create(nullptr, &impl_->ctx), "SUNContext_Create");
}

DfnSolver::~DfnSolver() = default;

void DfnSolver::start(double t0, const std::vector<double>& y0) {
  const int n = model_.size();
  Impl& im = *impl_;
  im.release();
  im.tn = t0;
  im.root_pending = false;
  t_ = t0;
  y_ = y0;
  yp_.assign(n, 0.0);

  const Impl::Structure& st = jacobian_structure(model_, y0);
  im.colptr = st.colptr;
  im.rowind = st.rowind;
  im.color = st.color;
  im.ncolors = st.ncolors;
  stats_.colors = im.ncolors;
  stats_.nonzeros = static_cast<long>(im.rowind.size());
  im.yd.resize(n);
  im.gd.resize(n);

  im.y = N_VNew_Serial(n, im.ctx);
  im.yp = N_VNew_Serial(n, im.ctx);
  im.atol = N_VNew_Serial(n, im.ctx);
  im.id = N_VNew_Serial(n, im.ctx);
  im.tmp = N_VNew_Serial(n, im.ctx);
  for (N_Vector v : {im.y, im.yp, im.atol, im.id, im.tmp}) use_fast_serial_ops(v);
  for (int i = 0; i < n; ++i) {
    NV_Ith_S(im.y, i) = y_[i];
    NV_Ith_S(im.yp, i) = 0.0;
    NV_Ith_S(im.atol, i) = settings_.atol * model_.abs_tolerance_scale()[i];
    NV_Ith_S(im.id, i) = model_.is_differential(i) ? 1.0 : 0.0;
  }
  im.ida = IDACreate(im.ctx);
  if (!im.ida) throw RuntimeFailure("IDACreate failed");
  check(IDASetErrHandlerFn(im.ida, keep_ida_message, nullptr), "IDASetErrHandlerFn");
  check(IDAInit(im.ida, residual_fn, t0, im.y, im.yp), "IDAInit");
  check(IDASetUserData(im.ida, impl_.get()), "IDASetUserData");
  check(IDASVtolerances(im.ida, settings_.rtol, im.atol), "IDASVtolerances");
  check(IDASetId(im.ida, im.id), "IDASetId");
  check(IDASetMaxNumSteps(im.ida, settings_.max_steps), "IDASetMaxNumSteps");
  // Large current steps (0 to 2C at full charge) need more Newton work to become consistent.
  // IDACalcIC's Newton keeps one Jacobian for up to this many iterations: from the rest state
  // (where the kinetics' slope is least) to 1C it converged linearly in about 36 iterations;
  // a fresh Jacobian after 10 converges in about 12 and stays within 20 Jacobians x 10.
  check(IDASetMaxNumItersIC(im.ida, 10), "IDASetMaxNumItersIC");
  check(IDASetMaxNumJacsIC(im.ida, 20), "IDASetMaxNumJacsIC");
  check(IDASetMaxNumStepsIC(im.ida, 20), "IDASetMaxNumStepsIC");
  im.jac = SUNSparseMatrix(n, n, static_cast<sunindextype>(im.rowind.size()), CSC_MAT, im.ctx);
  if (im.jac) use_fast_sparse_zero(im.jac);
  im.ls = SUNLinSol_KLU(im.y, im.jac, im.ctx);
  if (!im.jac || !im.ls) throw RuntimeFailure("cannot create the KLU sparse solver");
  im.ls->ops->initialize = klu_initialize_once;
  im.ls->ops->solve = klu_solve_refactor_on_nan;
  check(IDASetLinearSolver(im.ida, im.ls, im.jac), "IDASetLinearSolver");
  check(IDASetJacFn(im.ida, jacobian_fn), "IDASetJacFn");
  check(IDARootInit(im.ida, 4, root_fn), "IDARootInit");
  int dirs[4] = {-1, 1, -1, -1};
  check(IDASetRootDirection(im.ida, dirs), "IDASetRootDirection");
  check(IDASetNoInactiveRootWarn(im.ida), "IDASetNoInactiveRootWarn");
  consistent_init();
}

void DfnSolver::consistent_init() {
  Impl& im = *impl_;
  if (im.tn != t_) {  // the caller's state is interpolated: restart from it
    for (int i = 0; i < model_.size(); ++i) NV_Ith_S(im.y, i) = y_[i];
  }
  update_stats();
  stats_base_ = stats_;
  im.tn = t_;
  im.root_pending = false;
  im.window_steps0 = 0;
  im.window_t0 = t_;
  check(IDAReInit(im.ida, t_, im.y, im.yp), "IDAReInit");
  last_ida_message.clear();
  int flag = IDACalcIC(im.ida, IDA_YA_YDP_INIT, t_ + 1e-3);
  if (flag < 0) {
    const std::string first_message = last_ida_message;
    double reached = 0.0;
    if (settings_.ic_continuation) flag = continuation_init(reached);
    if (flag < 0) {
      std::string text = "IDACalcIC: no consistent state at t = " + std::to_string(t_) + " s (flag " +
                         std::to_string(flag) + ", " + flag_name(flag) + ")";
      if (!first_message.empty()) text += ": " + first_message;
      const Control& c = model_.control();
      const double* yv = y_.data();
      const bool by_voltage = c.kind == ControlKind::voltage;
      text += by_voltage ? "; asked for " + std::to_string(c.value) + " V from " +
                               std::to_string(model_.terminal_voltage_v(yv)) + " V"
                         : "; asked for " + std::to_string(model_.current_setpoint_a(t_)) + " A from " +
                               std::to_string(yv[model_.idx_current()]) + " A";
      text += " (a continuation in the setpoint got " + std::to_string(static_cast<int>(100.0 * reached)) +
              " % of the way); " + describe(nearest_surface_limit(model_, yv));
      last_ida_message.clear();
      throw RuntimeFailure(text);
    }
  }
  check(IDAGetConsistentIC(im.ida, im.y, im.yp), "IDAGetConsistentIC");
  const int n = model_.size();
  for (int i = 0; i < n; ++i) {
    y_[i] = NV_Ith_S(im.y, i);
    yp_[i] = NV_Ith_S(im.yp, i);
  }
  ++stats_.reinits;
}

// Newton from the previous state's algebraic variables does not always converge after a large
// step in the input: e.g. 2.5 A of discharge right after a CV charge that left the anode's
// surface at a stoichiometry of 0.997 (inventory_scale=1.005), where the exchange current
// (~ sqrt(1 - x)) is small and the first Newton iterates leave the region where the kinetics
// are well approximated by their linearisation. The differential states are fixed here, so the
// consistent state is a function of the setpoint alone: walk the setpoint from the state's own
// value (its current, or its terminal voltage under voltage control) to the target, each solve
// starting from the previous one, halving the walk's step on a failure and doubling it on a
// success. Called only after the direct solve failed, so runs that never needed it are
// unchanged bit for bit. Returns IDACalcIC's flag at the target (IDA then holds its solution)
// and in `reached` the fraction of the walk done.
int DfnSolver::continuation_init(double& reached) {
  Impl& im = *impl_;
  const Control target = model_.control();
  const int n = model_.size();
  const bool by_voltage = target.kind == ControlKind::voltage;
  // IDACalcIC leaves the vectors it was started from untouched: the first attempt's guess.
  std::vector<double> guess(n), guess_p(n);
  for (int i = 0; i < n; ++i) {
    guess[i] = NV_Ith_S(im.y, i);
    guess_p[i] = NV_Ith_S(im.yp, i);
  }
  const double from = by_voltage ? model_.terminal_voltage_v(guess.data()) : guess[model_.idx_current()];
  const double to = by_voltage ? target.value : model_.current_setpoint_a(t_);
  int flag = -1;
  double s = 0.0, ds = 0.25;
  constexpr double kMinStep = 1.0 / 1024.0;
  while (s < 1.0) {
    const double s1 = std::min(1.0, s + ds);
    Control c = target;
    if (s1 < 1.0) {
      c = Control{};
      c.kind = by_voltage ? ControlKind::voltage : ControlKind::current;
      c.value = from + s1 * (to - from);
    }
    model_.set_control(c);
    for (int i = 0; i < n; ++i) {
      NV_Ith_S(im.y, i) = guess[i];
      NV_Ith_S(im.yp, i) = guess_p[i];
    }
    update_stats();
    stats_base_ = stats_;
    check(IDAReInit(im.ida, t_, im.y, im.yp), "IDAReInit");
    flag = IDACalcIC(im.ida, IDA_YA_YDP_INIT, t_ + 1e-3);
    if (flag >= 0) {
      if (s1 >= 1.0) break;  // IDA holds the target's solution
      check(IDAGetConsistentIC(im.ida, im.y, im.yp), "IDAGetConsistentIC");
      for (int i = 0; i < n; ++i) {
        guess[i] = NV_Ith_S(im.y, i);
        guess_p[i] = NV_Ith_S(im.yp, i);
      }
      s = s1;
      ds *= 2.0;
    } else {
      ds *= 0.5;
      if (ds < kMinStep) break;
    }
  }
  model_.set_control(target);
  reached = flag >= 0 ? 1.0 : s;
  // The walk's failed attempts are not the caller's error.
  if (flag >= 0) last_ida_message.clear();
  return flag;
}

void DfnSolver::switch_control(const Control& control, const StopConditions& stop) {
  model_.set_control(control);
  stop_ = stop;
  consistent_init();
}

void DfnSolver::restart() { consistent_init(); }

void DfnSolver::set_state(const std::vector<double>& y) {
  Impl& im = *impl_;
  y_ = y;
  for (int i = 0; i < model_.size(); ++i) NV_Ith_S(im.y, i) = y_[i];
  consistent_init();
}

DfnSolver::Result DfnSolver::advance_to(double tout) { return advance(tout, false); }
DfnSolver::Result DfnSolver::advance_exactly_to(double tout) { return advance(tout, true); }

DfnSolver::Result DfnSolver::advance(double tout, bool exact) {
  Impl& im = *impl_;
  if (tout <= t_) return Result::reached;
  // One internal step at a time, then interpolate: far cheaper than IDA_NORMAL's per-call
  // overhead when output is dense (0.2 s) and steps are long.
  // IDA may already have stepped past tout; then the interpolated state is used and a
  // following restart() re-initialises from it.
  // With a root pending IDA's own time is already past it (possibly past tout): no stop time.
  if (exact && im.tn < tout && !im.root_pending) check(IDASetStopTime(im.ida, tout), "IDASetStopTime");
  else exact = false;
  const int n = model_.size();
  int restarts = 0;
  bool small_first_step = false;
  const auto wall0 = std::chrono::steady_clock::now();
  long steps_here = 0;
  while (!im.root_pending && im.tn < tout) {
    throw_if_interrupted();  // SIGINT/SIGTERM: every command stops within one solver step
    if (++steps_here > settings_.max_steps || (steps_here % 64 == 0 && wall_limit_passed(wall0))) {
      if (exact) IDASetStopTime(im.ida, 1e300);
      throw SolverLimitExceeded(limit_message(tout, steps_here > settings_.max_steps));
    }
    realtype tret = im.tn;
    const int flag = IDASolve(im.ida, tout, &tret, im.y, im.yp, IDA_ONE_STEP);
    if (flag < 0) {
      restart_after_failed_step(tret, tout, flag, exact, restarts);
      small_first_step = true;
      continue;
    }
    if (small_first_step) {  // back to IDA's own estimate for later re-initialisations
      check(IDASetInitStep(im.ida, 0.0), "IDASetInitStep");
      small_first_step = false;
    }
    if (flag == IDA_ROOT_RETURN) {
      // IDA's y is the state at the root; its internal step may reach past both.
      im.root_pending = true;
      im.root_t = tret;
      check(IDAGetRootInfo(im.ida, im.roots), "IDAGetRootInfo");
      break;
    }
    im.tn = tret;
    if (flag == IDA_TSTOP_RETURN) im.tn = tout;
    check_crawl(exact);
  }
  if (exact) IDASetStopTime(im.ida, 1e300);  // SUNDIALS 6.4 has no IDAClearStopTime
  if (im.root_pending && im.root_t <= tout) return stop_at_root();
  if (!im.root_pending && im.tn == tout) {
    for (int i = 0; i < n; ++i) y_[i] = NV_Ith_S(im.y, i);
  } else {
    check(IDAGetDky(im.ida, tout, 0, im.tmp), "IDAGetDky");
    for (int i = 0; i < n; ++i) y_[i] = NV_Ith_S(im.tmp, i);
  }
  t_ = tout;
  update_stats();
  return Result::reached;
}

// IDA could not take a step even after cutting it (repeated error-test or Newton failures):
// it returns its last accepted state, at tret. Restart there, as after a discontinuity
// (consistent algebraic variables, order 1) with a first step far below the last one, at most
// kMaxStepRestarts times in one call (not reset by a later step: a state IDA can only leave by
// tiny steps is a failure, not a reason to crawl on). Throws RuntimeFailure when it cannot.
void DfnSolver::restart_after_failed_step(double tret, double tout, int flag, bool exact, int& restarts) {
  Impl& im = *impl_;
  const std::string ida_message = last_ida_message;
  last_ida_message.clear();
  realtype h_last = 0.0;
  IDAGetLastStep(im.ida, &h_last);
  if (++restarts <= kMaxStepRestarts && tret >= im.tn && tret < tout) {
    const double caller_t = t_;
    const std::vector<double> caller_y = y_;
    t_ = im.tn = tret;  // im.y holds IDA's state at tret
    for (int i = 0; i < model_.size(); ++i) y_[i] = NV_Ith_S(im.y, i);
    const double h0 = std::abs(h_last) > 0.0 ? 1e-3 * std::abs(h_last) : 1e-6;
    check(IDASetInitStep(im.ida, std::min(h0, 0.5 * (tout - tret))), "IDASetInitStep");
    try {
      consistent_init();  // also IDAReInit: the stop time (if any) stays set
    } catch (const RuntimeFailure&) {
      t_ = caller_t;
      y_ = caller_y;
      if (exact) IDASetStopTime(im.ida, 1e300);
      IDASetInitStep(im.ida, 0.0);
      throw;
    }
    return;
  }
  if (exact) IDASetStopTime(im.ida, 1e300);
  IDASetInitStep(im.ida, 0.0);
  throw RuntimeFailure(step_failure_text(tret, tout, flag, h_last, restarts - 1, ida_message));
}

std::string DfnSolver::step_failure_text(double tret, double tout, int flag, double h_last, int restarts,
                                         const std::string& ida_message) const {
  std::string text = "IDA could not step on from t = " + std::to_string(tret) + " s towards " + std::to_string(tout) +
                     " s (flag " + std::to_string(flag) + ", " + flag_name(flag) + ", last step " +
                     std::to_string(h_last) + " s, after " + std::to_string(restarts) + " restarts)";
  if (!ida_message.empty()) text += ": " + ida_message;
  return text + "; " + describe(nearest_surface_limit(model_, N_VGetArrayPointer(impl_->y)));
}

// The state at the stop condition IDA found (its y holds the state at the root).
DfnSolver::Result DfnSolver::stop_at_root() {
  Impl& im = *impl_;
  im.root_pending = false;
  im.tn = t_ = im.root_t;
  for (int i = 0; i < model_.size(); ++i) y_[i] = NV_Ith_S(im.y, i);
  cause_ = StopCause{};
  cause_.voltage_below = im.roots[0] != 0;
  cause_.voltage_above = im.roots[1] != 0;
  cause_.current_below = im.roots[2] != 0;
  cause_.surface_stoich = im.roots[3] != 0;
  update_stats();
  return Result::stopped;
}

bool DfnSolver::wall_limit_passed(std::chrono::steady_clock::time_point since) const {
  return std::chrono::duration<double>(std::chrono::steady_clock::now() - since).count() > settings_.max_wall_s;
}

std::string DfnSolver::limit_message(double tout, bool by_steps) const {
  const Impl& im = *impl_;
  realtype h_last = 0.0;
  IDAGetLastStep(im.ida, &h_last);
  char buf[512];
  if (by_steps)
    std::snprintf(buf, sizeof buf, "solver step limit: %ld internal steps from t = %.6g s did not reach %.6g s (now at %.9g s, last step %.3g s)",
                  settings_.max_steps, t_, tout, im.tn, h_last);
  else
    std::snprintf(buf, sizeof buf, "solver wall-clock limit: %.0f s spent from t = %.6g s towards %.6g s (now at %.9g s, last step %.3g s)",
                  settings_.max_wall_s, t_, tout, im.tn, h_last);
  return std::string(buf) + kLimitAdvice;
}

void DfnSolver::check_crawl(bool exact) {
  Impl& im = *impl_;
  long nst = 0;
  IDAGetNumSteps(im.ida, &nst);
  if (nst - im.window_steps0 < settings_.crawl_window_steps) return;
  const double advanced_s = im.tn - im.window_t0;
  if (advanced_s < settings_.crawl_min_advance_s) {
    realtype h_last = 0.0;
    IDAGetLastStep(im.ida, &h_last);
    long conv_fails = 0;
    IDAGetNumNonlinSolvConvFails(im.ida, &conv_fails);
    if (exact) IDASetStopTime(im.ida, 1e300);
    char buf[512];
    std::snprintf(buf, sizeof buf,
                  "solver is crawling: %ld steps from t = %.9g s advanced the model by only %.3g s (last step %.3g s, "
                  "%ld Newton convergence failures since the last restart)",
                  nst - im.window_steps0, im.window_t0, advanced_s, h_last, conv_fails);
    throw RuntimeFailure(std::string(buf) + kLimitAdvice);
  }
  im.window_steps0 = nst;
  im.window_t0 = im.tn;
}

void DfnSolver::update_stats() {
  Impl& im = *impl_;
  long v = 0;
  IDAGetNumSteps(im.ida, &v);
  stats_.steps = stats_base_.steps + v;
  IDAGetNumResEvals(im.ida, &v);
  stats_.residual_evals = stats_base_.residual_evals + v;
  IDAGetNumJacEvals(im.ida, &v);
  stats_.jacobian_evals = stats_base_.jacobian_evals + v;
}

}  // namespace bms
