#include "diagnosis/diagnose.hpp"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <chrono>
#include <cmath>
#include <atomic>
#include <map>
#include <memory>
#include <mutex>

#include "diagnosis/minimise.hpp"
#include "diagnosis/normal_equations.hpp"
#include "diagnosis/parallel.hpp"
#include "io/input_error.hpp"
#include "io/statistics.hpp"

namespace bms::diagnosis {

namespace {

// Objective value of a parameter for which the solver fails: worse than any real fit.
constexpr double kFailedRunMv = 1e6;
// Cached model runs before the cache is emptied (each is one voltage per sample).
constexpr std::size_t kCacheRuns = 256;
// --initial-soc auto: a first rest voltage this close to the default state's is that state.
constexpr double kStartsFullV = 5e-3;
// ... or whose state lies within this share of the capacity of it.
constexpr double kStartsFullShare = 0.05;
// A first sample below this current counts as rest (an ADC's offset at zero current).
constexpr double kRestShare = 0.02;
constexpr double kRestCurrentA = 2e-3;

// Where each knob is searched. The ranges cover the sizes of models.md section 5 several
// times over; factors on the cell's parameters are searched in log10 over x0.05..x10.
struct SearchSpace {
  double lo, hi, tol;
  bool log10;  // search in log10(value)
  double value(double x) const { return log10 ? std::pow(10.0, x) : x; }
  double x_of(double v) const { return log10 ? std::log10(v) : v; }
};

SearchSpace search_space(Effect e, double max_abs_current_a, double dt_s) {
  switch (e) {
    case Effect::contact_resistance: return {0.0, 0.02, 2e-5, false};
    case Effect::hysteresis: return {0.0, 0.05, 5e-5, false};
    case Effect::current_offset: {
      const double w = 0.02 * std::max(max_abs_current_a, 0.1);
      return {-w, w, 2e-3 * w, false};
    }
    case Effect::current_gain: return {-0.05, 0.05, 1e-4, false};
    case Effect::thermal: return {-2.5, 1.5, 2e-3, true};  // 3 mW/K (adiabatic-like) .. 30 W/K (isothermal)
    // Log-space spread of the cathode radius; beyond 0.9 the largest of 3 populations is 5x R
    // (25x the diffusion time) and IDA finds no consistent start at 2C.
    case Effect::particle_size: return {0.0, 0.9, 1e-3, false};
    case Effect::voltage_offset: return {-0.05, 0.05, 2e-5, false};
    case Effect::voltage_gain: return {-0.03, 0.03, 1e-5, false};
    case Effect::rc_branch: return {0.0, 0.05, 2e-5, false};
    // From 10 s: faster relaxation is the contact resistance's and the DFN's own.
    case Effect::rc_time_constant: return {1.0, 3.7, 2e-3, true};
    case Effect::time_skew: return {-5.0 * dt_s, 5.0 * dt_s, 1e-3 * dt_s, false};
    case Effect::i0_positive:
    case Effect::i0_negative: return {-1.5, 1.5, 2e-3, true};
    // Over-full starts put the stoichiometries past the cell window, where the solver crawls.
    case Effect::initial_soc: return {-0.1, 0.01, 1e-4, false};
    // Three decades slower to one faster at full lithiation; the knee inside the LFP plateau.
    case Effect::diffusivity_profile_positive: return {-3.0, 1.0, 2e-3, false};
    case Effect::diffusivity_profile_knee: return {0.3, 0.95, 1e-3, false};
    // 1 mohm m2 to 10 ohm m2 of particle surface below the knee (an 18650's 25 m2 of cathode
    // surface: 0.04 to 400 mohm at the cell), rising up to four decades to full lithiation.
    case Effect::resistive_reactant_positive: return {-3.0, 1.0, 2e-3, true};
    case Effect::resistive_reactant_log10: return {0.0, 4.0, 2e-3, false};
    case Effect::resistive_reactant_knee: return {0.3, 0.95, 1e-3, false};
    default: break;
  }
  return {-1.3, 1.0, 2e-3, true};  // factors on the cell's parameters
}

// The value a knob has before it is fitted: no effect.
double neutral_value(Effect e) {
  if (e == Effect::rc_time_constant) return 100.0;
  if (e == Effect::diffusivity_profile_knee || e == Effect::resistive_reactant_knee) return 0.5;
  return truth_parameter_of(e)[0] != '\0' ? 1.0 : 0.0;
}

void set_knob(Hypothesis& h, Effect e, double v) {
  for (auto& s : h)
    if (s.effect == e) {
      s.value = v;
      return;
    }
  h.push_back({e, v});
}

bool has_knob(const Hypothesis& h, Effect e) {
  return std::any_of(h.begin(), h.end(), [e](const EffectSetting& s) { return s.effect == e; });
}

// Small normal equations and the Fisher information in matrices of bounded size: the host
// links the firmware's EIGEN_NO_MALLOC, so nothing here may allocate.
constexpr std::size_t kMaxFisherKnobs = 16;
using SmallMatrix = BoundedMatrix<static_cast<int>(kMaxFisherKnobs)>;
using SmallVector = BoundedVector<static_cast<int>(kMaxFisherKnobs)>;

// Pooled sums of squares over several cases.
struct Pool {
  double sum2 = 0.0, max_abs = 0.0;
  std::size_t n = 0;
  void add(const std::vector<double>& r, const std::vector<char>& use) {
    for (std::size_t k = 0; k < r.size(); ++k) {
      if (!use.empty() && !use[k]) continue;
      sum2 += r[k] * r[k];
      max_abs = std::max(max_abs, std::abs(r[k]));
      ++n;
    }
  }
  double rms() const { return n ? std::sqrt(sum2 / static_cast<double>(n)) : 0.0; }
};

// Per case: which samples train (or validate) in this fold; empty = the case is not used.
struct Fold {
  std::vector<std::vector<char>> train, validate;
};

// Runs the model (cached by the knobs that need a run) and applies the post knobs. Search
// runs carry the plain model's final-minus-search difference, so a fit sees the effect, not
// the mesh. Safe to call from several threads: runs are shared, read-only, and a run gives the
// same voltages whichever thread makes it (or makes it twice).
class Evaluator {
 public:
  using Run = std::shared_ptr<const std::vector<double>>;
  Evaluator(const std::vector<CaseResult>& cases, ModelSetup search, ModelSetup final_setup)
      : cases_(cases), search_(std::move(search)), final_(std::move(final_setup)), delta_(cases.size()) {}

  std::vector<double> voltage(std::size_t c, const Hypothesis& h, bool final_mesh) {
    const Run raw = run(c, h, final_mesh);
    std::vector<double> v = *raw;
    if (!final_mesh && !delta_[c].empty())
      for (std::size_t k = 0; k < v.size(); ++k) v[k] += std::isfinite(delta_[c][k]) ? delta_[c][k] : 0.0;
    const Record& r = *cases_[c].record;
    return apply_post(h, r.t_s, r.current_a, v);
  }
  std::vector<double> residual(std::size_t c, const Hypothesis& h, bool final_mesh) {
    return residual_mv(voltage(c, h, final_mesh), *cases_[c].record);
  }
  Run run(std::size_t c, const Hypothesis& h, bool final_mesh) {
    Hypothesis knobs;
    const std::string key = key_of(c, h, final_mesh, knobs);
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      if (auto it = pinned_.find(key); it != pinned_.end()) return it->second;
      if (auto it = cache_.find(key); it != cache_.end()) return it->second;
    }
    ++runs_;
    Run v = std::make_shared<const std::vector<double>>(run_model(setup(final_mesh), *cases_[c].record, knobs).voltage_v);
    const std::lock_guard<std::mutex> lock(mutex_);
    if (cache_.size() >= kCacheRuns) cache_.clear();
    return cache_.emplace(key, std::move(v)).first->second;
  }
  // A run kept for the whole diagnosis (the plain model's).
  void put(std::size_t c, const Hypothesis& h, bool final_mesh, std::vector<double> v) {
    Hypothesis knobs;
    const std::string key = key_of(c, h, final_mesh, knobs);
    const std::lock_guard<std::mutex> lock(mutex_);
    pinned_[key] = std::make_shared<const std::vector<double>>(std::move(v));
  }
  const ModelSetup& setup(bool final_mesh) const { return final_mesh ? final_ : search_; }
  void set_delta(std::size_t c, std::vector<double> d) { delta_[c] = std::move(d); }
  int runs() const { return runs_; }

 private:
  // The knobs that need a run, in a fixed order, and the cache key they make.
  static std::string key_of(std::size_t c, const Hypothesis& h, bool final_mesh, Hypothesis& knobs) {
    for (const auto& s : h)
      if (knob_kind(s.effect) != KnobKind::post && s.value != neutral_value(s.effect)) knobs.push_back(s);
    std::sort(knobs.begin(), knobs.end(), [](auto& a, auto& b) { return a.effect < b.effect; });
    std::string key = fmt::format("{}/{}", c, final_mesh ? 'f' : 's');
    for (const auto& s : knobs) key += fmt::format("/{}={:.17g}", static_cast<int>(s.effect), s.value);
    return key;
  }
  const std::vector<CaseResult>& cases_;
  ModelSetup search_, final_;
  std::vector<std::vector<double>> delta_;
  std::mutex mutex_;
  std::map<std::string, Run> cache_, pinned_;
  std::atomic<int> runs_{0};
};

struct Context {
  const DiagnoseSettings& settings;
  std::vector<CaseResult>& cases;
  Evaluator& eval;
  std::vector<Fold> folds;
  Fold all;  // the fit reported as "after"
  double imax = 0.0, dt_s = 1.0;
  std::function<void(const std::string&)> say;
  double floor_mv = 0.0;  // set once the plain model has run
  int threads = 1;
};

double train_rmse(Context& ctx, const Hypothesis& h, const Fold& fold) {
  Pool p;
  try {
    for (std::size_t c = 0; c < ctx.cases.size(); ++c)
      if (!fold.train[c].empty()) p.add(ctx.eval.residual(c, h, false), fold.train[c]);
  } catch (const RuntimeFailure&) {
    return kFailedRunMv;
  }
  return p.rms();
}

struct FitResult {
  Hypothesis h;
  double train_mv = 0.0;
  int evaluations = 0;
};

// Coordinate search over `knobs` (others fixed): a grid over the whole range, golden section
// around its best point; `narrow` searches only around the current value. Used for knobs that
// need no model run (the measurement structure), where an evaluation costs nothing.
FitResult fit_by_grid(Context& ctx, Hypothesis h, const std::vector<Effect>& knobs, const Fold& fold, bool narrow) {
  FitResult out;
  const bool post_only = std::all_of(knobs.begin(), knobs.end(), [](Effect k) { return knob_kind(k) == KnobKind::post; });
  const int sweeps = knobs.size() > 1 && post_only ? 3 : 1;
  for (int sweep = 0; sweep < sweeps; ++sweep) {
    for (Effect k : knobs) {
      const SearchSpace sp = search_space(k, ctx.imax, ctx.dt_s);
      double lo = sp.lo, hi = sp.hi;
      if (narrow || sweep > 0) {
        const double x0 = std::clamp(sp.x_of(knob_value(h, k)), sp.lo, sp.hi), w = 0.15 * (sp.hi - sp.lo);
        lo = std::max(sp.lo, x0 - w);
        hi = std::min(sp.hi, x0 + w);
      }
      auto objective = [&](double x) {
        Hypothesis t = h;
        set_knob(t, k, sp.value(x));
        return train_rmse(ctx, t, fold);
      };
      const auto m = minimise_bounded(objective, lo, hi, sp.tol, narrow || sweep > 0 ? 5 : 7);
      set_knob(h, k, sp.value(m.x));
      out.train_mv = m.f;
      out.evaluations += m.evaluations;
    }
  }
  out.h = std::move(h);
  return out;
}

// The training residual (mV) of a hypothesis, sample by sample over the fold's training
// samples; ok = false when the model failed.
struct TrainResidual {
  std::vector<double> r;
  double rms = kFailedRunMv;
  bool ok = false;
};

TrainResidual train_residual(Context& ctx, const Hypothesis& h, const Fold& fold) {
  TrainResidual out;
  try {
    for (std::size_t c = 0; c < ctx.cases.size(); ++c) {
      if (fold.train[c].empty()) continue;
      const auto res = ctx.eval.residual(c, h, false);
      for (std::size_t k = 0; k < res.size(); ++k)
        if (fold.train[c][k]) out.r.push_back(res[k]);
    }
  } catch (const RuntimeFailure&) {
    out.r.clear();
    return out;
  }
  double s2 = 0.0;
  for (double x : out.r) s2 += x * x;
  out.rms = out.r.empty() ? 0.0 : std::sqrt(s2 / static_cast<double>(out.r.size()));
  out.ok = true;
  return out;
}

// Gauss-Newton steps with Levenberg-Marquardt damping on the knobs (in their search variables,
// inside their ranges). The Jacobian of the training residual starts from forward differences
// (one run per knob that needs a run; none for the measurement structure) and is then kept up
// to date from the runs the steps make anyway (Broyden's secant update: for one knob the slope
// through the last two points). It stops when the step is within the knobs' tolerances, when
// the predicted gain is invisible against the residual's floor, or when steps stop improving.
constexpr int kMaxFitSteps = 10;
constexpr int kMaxFailedSteps = 3;
// A step that would gain less than this share of the floor (RMS, mV) is not taken.
constexpr double kInvisibleGainShare = 1e-3;
// Forward-difference step: this share of the knob's range. Not smaller: a drive correction
// changes where the current's pieces and steps fall, which makes the voltage a slightly rough
// function of the knob; a 1 % difference of a current-sensor gain on a drive cycle saw that
// roughness instead of the slope (the secant updates refine the slope anyway).
constexpr double kDifferenceShare = 0.05;
// Grid points that seed the fit of a drive correction.
constexpr int kDriveSeedPoints = 5;
// One step moves a knob by at most this share of its range (the response is not linear far out).
constexpr double kMaxStepShare = 0.35;

// J^T J and J^T r.
void normal_equations(const Columns& jac, const std::vector<double>& r, SmallMatrix& a, SmallVector& g) {
  a = gram<static_cast<int>(kMaxFisherKnobs)>(jac);
  g = gradient<static_cast<int>(kMaxFisherKnobs)>(jac, r);
}

// The damped Gauss-Newton step from x, shortened to stay near the linearisation and clipped
// to the ranges: the trial point xt and dx = xt - x. True when every |dx| is within its knob's
// tolerance (converged, or pressed against a bound).
bool damped_step(const SmallMatrix& a, const SmallVector& g, double lambda, const std::vector<SearchSpace>& sp,
                 const std::vector<double>& x, std::vector<double>& xt, std::vector<double>& dx) {
  const std::size_t p = x.size();
  SmallMatrix damped = a;
  for (Eigen::Index j = 0; j < damped.rows(); ++j) damped(j, j) += (lambda + 1e-12) * std::max(a(j, j), 1e-300);
  const SmallVector solved = damped.ldlt().solve(-g);
  double shrink = 1.0;
  for (std::size_t j = 0; j < p; ++j) {
    const double d = std::abs(solved(static_cast<Eigen::Index>(j))), lim = kMaxStepShare * (sp[j].hi - sp[j].lo);
    if (std::isfinite(d) && d > lim) shrink = std::min(shrink, lim / d);
  }
  xt.assign(p, 0.0);
  dx.assign(p, 0.0);
  bool small = true;
  for (std::size_t j = 0; j < p; ++j) {
    const double sj = solved(static_cast<Eigen::Index>(j));
    xt[j] = std::clamp(x[j] + (std::isfinite(sj) ? shrink * sj : 0.0), sp[j].lo, sp[j].hi);
    dx[j] = xt[j] - x[j];
    small = small && std::abs(dx[j]) < sp[j].tol;
  }
  return small;
}

// The RMS the linear model predicts after dx: |r + J dx|^2 = |r|^2 + 2 g.dx + dx.A.dx.
double predicted_rms(double rms, std::size_t m, const SmallMatrix& a, const SmallVector& g, const std::vector<double>& dx) {
  double ss = rms * rms * static_cast<double>(m);
  for (std::size_t j = 0; j < dx.size(); ++j) {
    ss += 2.0 * g(static_cast<Eigen::Index>(j)) * dx[j];
    for (std::size_t l = 0; l < dx.size(); ++l) ss += dx[j] * a(static_cast<Eigen::Index>(j), static_cast<Eigen::Index>(l)) * dx[l];
  }
  return std::sqrt(std::max(ss, 0.0) / static_cast<double>(std::max<std::size_t>(m, 1)));
}

// Broyden: J += (dr - J dx) dx^T / |dx|^2 (for one knob: the secant through the two points).
void broyden_update(Columns& jac, const std::vector<double>& r0, const std::vector<double>& r1, const std::vector<double>& dx) {
  double dx2 = 0.0;
  for (double d : dx) dx2 += d * d;
  if (!(dx2 > 0.0)) return;
  for (std::size_t i = 0; i < r0.size(); ++i) {
    double y = r1[i] - r0[i];
    for (std::size_t j = 0; j < dx.size(); ++j) y -= jac[j][i] * dx[j];
    for (std::size_t j = 0; j < dx.size(); ++j) jac[j][i] += y * dx[j] / dx2;
  }
}

// Forward differences of the training residual at x, one knob at a time (the other side of
// x when a run fails there; a zero column when both fail).
template <class At>
Columns forward_jacobian(Context& ctx, const Fold& fold, const std::vector<SearchSpace>& sp, const std::vector<double>& x,
                         const TrainResidual& cur, const At& at, int& evaluations) {
  Columns jac(x.size());
  for (std::size_t j = 0; j < x.size(); ++j) {
    const double range = sp[j].hi - sp[j].lo;
    double dx = kDifferenceShare * range * (x[j] + kDifferenceShare * range > sp[j].hi ? -1.0 : 1.0);
    std::vector<double> xp = x;
    xp[j] += dx;
    TrainResidual rp = train_residual(ctx, at(xp), fold);
    ++evaluations;
    if (!rp.ok) {
      dx = -dx;
      xp[j] = x[j] + dx;
      rp = train_residual(ctx, at(xp), fold);
      ++evaluations;
    }
    jac[j].assign(cur.r.size(), 0.0);
    if (rp.ok)
      for (std::size_t i = 0; i < cur.r.size(); ++i) jac[j][i] = (rp.r[i] - cur.r[i]) / dx;
  }
  return jac;
}

FitResult fit_by_gauss_newton(Context& ctx, Hypothesis h, const std::vector<Effect>& knobs, const Fold& fold) {
  const std::size_t p = knobs.size();
  std::vector<SearchSpace> sp;
  std::vector<double> x(p);
  for (std::size_t j = 0; j < p; ++j) {
    sp.push_back(search_space(knobs[j], ctx.imax, ctx.dt_s));
    x[j] = std::clamp(sp[j].x_of(knob_value(h, knobs[j], neutral_value(knobs[j]))), sp[j].lo, sp[j].hi);
  }
  auto at = [&](const std::vector<double>& xs) {
    Hypothesis t = h;
    for (std::size_t j = 0; j < p; ++j) set_knob(t, knobs[j], sp[j].value(xs[j]));
    return t;
  };
  FitResult out;
  TrainResidual cur = train_residual(ctx, at(x), fold);
  ++out.evaluations;
  if (!cur.ok) return fit_by_grid(ctx, h, knobs, fold, false);  // no point to linearise at
  Columns jac = forward_jacobian(ctx, fold, sp, x, cur, at, out.evaluations);
  double lambda = 0.0;
  int failed = 0;
  bool moved = false;
  SmallMatrix a;
  SmallVector g;
  std::vector<double> xt, dx;
  for (int step = 0; step < kMaxFitSteps && failed < kMaxFailedSteps; ++step) {
    normal_equations(jac, cur.r, a, g);
    if (damped_step(a, g, lambda, sp, x, xt, dx)) break;
    if (lambda == 0.0 && cur.rms - predicted_rms(cur.rms, cur.r.size(), a, g, dx) < kInvisibleGainShare * ctx.floor_mv)
      break;  // what is left to gain is invisible against the floor
    TrainResidual trial = train_residual(ctx, at(xt), fold);
    ++out.evaluations;
    if (trial.ok) broyden_update(jac, cur.r, trial.r, dx);
    if (trial.ok && trial.rms < cur.rms) {
      const double gain = cur.rms - trial.rms;
      x = xt;
      cur = std::move(trial);
      lambda = lambda > 1e-3 ? lambda / 4.0 : 0.0;
      failed = 0;
      moved = true;
      if (gain < kInvisibleGainShare * ctx.floor_mv) break;  // stopped improving
    } else {
      lambda = lambda == 0.0 ? 1.0 : 4.0 * lambda;
      ++failed;
    }
  }
  if (failed >= kMaxFailedSteps && !moved) {
    // Not one step downhill from the start: the linearisation does not describe the knob
    // here; the grid over the whole range does not need it.
    FitResult grid = fit_by_grid(ctx, h, knobs, fold, false);
    grid.evaluations += out.evaluations;
    return grid;
  }
  out.h = at(x);
  out.train_mv = cur.rms;
  return out;
}

// A coarse grid over several knobs (their values per axis, the first axis outermost) picks the
// start: the best point, or h itself when no point is better; returns the runs it took.
using GridAxis = std::pair<Effect, std::vector<double>>;
int seed_by_grid(Context& ctx, Hypothesis& h, const Fold& fold, const std::vector<GridAxis>& axes) {
  double best_f = train_rmse(ctx, h, fold);
  int runs = 1;
  Hypothesis best = h;
  std::vector<std::size_t> at(axes.size(), 0);
  for (;;) {
    Hypothesis t = h;
    for (std::size_t a = 0; a < axes.size(); ++a) set_knob(t, axes[a].first, axes[a].second[at[a]]);
    const double f = train_rmse(ctx, t, fold);
    ++runs;
    if (f < best_f) {
      best_f = f;
      best = std::move(t);
    }
    std::size_t a = axes.size();
    while (a > 0 && ++at[a - 1] == axes[a - 1].second.size()) at[--a] = 0;
    if (a == 0) break;
  }
  h = std::move(best);
  return runs;
}

// The effects whose start a coarse grid over their knobs picks (empty: none). The diffusivity
// profile moves the end of a discharge by many minutes, and its knee does nothing while the
// profile is flat: Gauss-Newton from the plain model stayed at it on records made with a
// profile. The resistive reactant has the same trouble (its rise and knee do nothing while its
// resistance is off). Self-heating lowers the resistance as a discharge goes on, and more at a
// higher rate; from the isothermal model Gauss-Newton sees only its small first-order effect and
// stayed there on the About:Energy records, where 0.04-0.1 W/K (an 18650 in free air) fits with a
// resistive reactant.
std::vector<GridAxis> seed_axes_of(Effect e) {
  switch (e) {
    case Effect::diffusivity_profile_positive:
      return {{Effect::diffusivity_profile_positive, {-2.0, -1.0, -0.5}},
              {Effect::diffusivity_profile_knee, {0.5, 0.7, 0.85}}};
    case Effect::resistive_reactant_positive:
      return {{Effect::resistive_reactant_positive, {0.01, 0.1, 0.3}},
              {Effect::resistive_reactant_log10, {1.0, 2.0, 3.0}},
              {Effect::resistive_reactant_knee, {0.3, 0.6, 0.75}}};
    case Effect::thermal: return {{Effect::thermal, {0.03, 0.1, 0.3, 1.0}}};
    default: return {};
  }
}

bool has_seed_grid(Effect e) { return !seed_axes_of(e).empty(); }

// The seed grids of a combination's effects searched together: an effect fitted alone can sit in
// a basin the combination does not share (on the About:Energy records the reactant alone fits a
// knee at 0.37 and 460x, and self-heating added to it stayed near isothermal, 52 mV held out; the
// two searched together fit a knee near 0.55, about 5000x and 0.1 W/K, 36 mV). Over
// kMaxJointSeedPoints, one grid at a time.
constexpr std::size_t kMaxJointSeedPoints = 150;
int reseed_combination(Context& ctx, Hypothesis& h, const Fold& fold) {
  std::vector<std::vector<GridAxis>> grids;
  for (const auto& setting : h)
    if (auto axes = seed_axes_of(setting.effect); !axes.empty()) grids.push_back(std::move(axes));
  std::vector<GridAxis> joint;
  std::size_t points = 1;
  for (const auto& g : grids)
    for (const auto& axis : g) {
      joint.push_back(axis);
      points *= axis.second.size();
    }
  if (joint.empty()) return 0;
  if (points <= kMaxJointSeedPoints) return seed_by_grid(ctx, h, fold, joint);
  int runs = 0;
  for (const auto& g : grids) runs += seed_by_grid(ctx, h, fold, g);
  return runs;
}

// Knobs that need model runs are fitted by Gauss-Newton (a few runs each); knobs applied to
// the model's voltage only by the grid (free).
FitResult fit_knobs(Context& ctx, Hypothesis h, const std::vector<Effect>& knobs, const Fold& fold, bool narrow) {
  for (Effect k : knobs)
    if (!has_knob(h, k)) h.push_back({k, neutral_value(k)});
  const bool post_only = std::all_of(knobs.begin(), knobs.end(), [](Effect k) { return knob_kind(k) == KnobKind::post; });
  if (post_only) return fit_by_grid(ctx, std::move(h), knobs, fold, narrow);
  int seed_evaluations = 0;
  if (!narrow && knobs.size() == 1 && knob_kind(knobs.front()) == KnobKind::drive) {
    // A drive correction (current-sensor offset or gain, start state) moves every later state:
    // on a drive cycle the residual is far from linear in it, and Gauss-Newton from the plain
    // model stopped at a sixth of a 3 % gain. A coarse grid over the range picks the start.
    const SearchSpace sp = search_space(knobs.front(), ctx.imax, ctx.dt_s);
    double best_x = sp.x_of(knob_value(h, knobs.front())), best_f = HUGE_VAL;
    for (int k = 0; k < kDriveSeedPoints; ++k) {
      const double x = sp.lo + (sp.hi - sp.lo) * k / (kDriveSeedPoints - 1);
      Hypothesis t = h;
      set_knob(t, knobs.front(), sp.value(x));
      const double f = train_rmse(ctx, t, fold);
      ++seed_evaluations;
      if (f < best_f) {
        best_f = f;
        best_x = x;
      }
    }
    set_knob(h, knobs.front(), sp.value(best_x));
  }
  if (!narrow && has_seed_grid(knobs.front()))
    seed_evaluations += seed_by_grid(ctx, h, fold, seed_axes_of(knobs.front()));
  FitResult out = fit_by_gauss_newton(ctx, std::move(h), knobs, fold);
  out.evaluations += seed_evaluations;
  return out;
}

struct Score {
  double heldout_mv = 0.0, all_mv = 0.0, max_abs_mv = 0.0;
  bool failed = false;
};

// Held-out RMSE of one hypothesis per fold, on the final mesh.
Score score(Context& ctx, const std::vector<Hypothesis>& per_fold) {
  Pool held, all;
  Score s;
  try {
    for (std::size_t f = 0; f < ctx.folds.size(); ++f)
      for (std::size_t c = 0; c < ctx.cases.size(); ++c) {
        if (ctx.folds[f].validate[c].empty()) continue;
        const auto r = ctx.eval.residual(c, per_fold[f], true);
        held.add(r, ctx.folds[f].validate[c]);
        all.add(r, {});
      }
  } catch (const RuntimeFailure&) {
    s.failed = true;
    s.heldout_mv = s.all_mv = kFailedRunMv;
    return s;
  }
  s.heldout_mv = held.rms();
  s.all_mv = all.rms();
  s.max_abs_mv = all.max_abs;
  return s;
}

std::vector<Effect> effects_in(const std::vector<Effect>& selected, Effect add) {
  std::vector<Effect> out;
  for (Effect e : selected)
    for (Effect k : knobs_of(e)) out.push_back(k);
  if (add != Effect::none)
    for (Effect k : knobs_of(add)) out.push_back(k);
  return out;
}

}  // namespace

void split_samples(std::size_t n, int blocks, std::vector<char>& train, std::vector<char>& validate) {
  train.assign(n, 0);
  validate.assign(n, 0);
  const auto b = static_cast<std::size_t>(std::max(2, blocks));
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t block = k * b / n;
    (block % 2 == 0 ? train : validate)[k] = 1;
  }
}

void set_initial_state(Record& r, const CellParameters& cell, const std::string& spec) {
  const double capacity_ah = cell.nominal_capacity_ah > 0 ? cell.nominal_capacity_ah : 1.0;
  if (spec == "full") return;
  if (spec != "auto") {
    char* end = nullptr;
    const double soc = std::strtod(spec.c_str(), &end);
    if (spec.empty() || *end != '\0' || !(soc >= 0.0 && soc <= 1.0))
      throw InputError("--initial-soc: '" + spec + "' is not auto, full or a state of charge in [0, 1]");
    r.initial_depth_ah = (1.0 - soc) * capacity_ah;
    r.initial_state_note = fmt::format("start at state of charge {:g} (given)", soc);
    return;
  }
  double imax = 0.0;
  for (double i : r.current_a) imax = std::max(imax, std::abs(i));
  if (std::abs(r.current_a.front()) > kRestShare * imax + kRestCurrentA) {
    r.initial_state_note = "the record starts under current: the cell's default (full) state";
    return;
  }
  const auto ic = default_initial_conditions(cell);
  const double v_full = cell.positive.ocp_v->value(ic.stoich_pos) - cell.negative.ocp_v->value(ic.stoich_neg);
  if (std::abs(r.voltage_v.front() - v_full) <= kStartsFullV) {
    r.initial_state_note = fmt::format("first rest voltage {:.4f} V is the default state's ({:.4f} V): start full",
                                       r.voltage_v.front(), v_full);
    return;
  }
  std::string note;
  const double depth_ah = depth_from_rest_voltage(cell, r.voltage_v.front(), &note);
  if (std::abs(depth_ah) < kStartsFullShare * capacity_ah) {
    // On the steep ends of the open-circuit curve a cell just charged has not relaxed yet: its
    // first voltage maps to a state a hair from full, and starting there costs more than it gives.
    r.initial_state_note = fmt::format("first rest voltage {:.4f} V maps to {:.4f} Ah from the default state (under "
                                       "{:g} % of the capacity): start full",
                                       r.voltage_v.front(), depth_ah, 100 * kStartsFullShare);
    return;
  }
  r.initial_depth_ah = depth_ah;
  r.initial_state_note = fmt::format(
      "first rest voltage {:.4f} V (the default state's is {:.4f} V): start {:.4f} Ah below it (state of charge {:.3f}){}",
      r.voltage_v.front(), v_full, r.initial_depth_ah, 1.0 - r.initial_depth_ah / capacity_ah,
      note.empty() ? "" : "; " + note);
}

namespace {

std::string knob_list(const Hypothesis& h) {
  std::string s;
  for (const auto& k : h) s += fmt::format("{}{} = {}", s.empty() ? "" : ", ", parameter_name(k.effect), format_value(k.effect, k.value));
  return s.empty() ? "-" : s;
}

std::string effect_list(const std::vector<Effect>& e) {
  std::string s;
  for (Effect x : e) s += (s.empty() ? "" : " + ") + std::string(effect_name(x));
  return s.empty() ? "none" : s;
}

struct Setup {
  double imax = 0.0, dt_s = 1.0;
  bool all_rest = true, all_constant = true;
};

// Cases, their roles and masks, state of charge and excitation.
Setup build_cases(const CellParameters& cell, const std::vector<Record>& records, const DiagnoseSettings& settings,
                  DiagnosisResult& out, const std::function<void(const std::string&)>& say) {
  Setup st;
  st.dt_s = HUGE_VAL;
  const double capacity_ah = cell.nominal_capacity_ah > 0 ? cell.nominal_capacity_ah : 1.0;
  for (std::size_t c = 0; c < records.size(); ++c) {
    CaseResult cr;
    const Record& rec = records[c];
    cr.record = &rec;
    cr.excitation = analyse_excitation(rec);
    st.imax = std::max(st.imax, cr.excitation.max_abs_current_a);
    st.all_rest = st.all_rest && cr.excitation.no_current;
    st.all_constant = st.all_constant && cr.excitation.constant_current_only;
    const std::size_t n = rec.t_s.size();
    std::vector<double> steps;
    for (std::size_t k = 1; k < n; ++k) steps.push_back(rec.t_s[k] - rec.t_s[k - 1]);
    st.dt_s = std::min(st.dt_s, stats::median(steps));
    if (records.size() == 1) {
      split_samples(n, settings.blocks, cr.train, cr.validate);
      cr.role = "train+validate";
    } else {
      cr.train.assign(n, 1);
      cr.validate.assign(n, 1);
      cr.role = "left out";
    }
    const double depth = std::isfinite(rec.initial_depth_ah) ? rec.initial_depth_ah : 0.0;
    cr.soc = state_of_charge(rec, 1.0 - depth / capacity_ah, capacity_ah);
    say(fmt::format("{}: {} samples over {:.0f} s; {}{}{}", rec.source, n, rec.duration_s(), cr.excitation.describe(),
                    rec.layout_note.empty() ? "" : "; " + rec.layout_note,
                    rec.initial_state_note.empty() ? "" : "; " + rec.initial_state_note));
    out.cases.push_back(std::move(cr));
  }
  if (st.all_constant && records.size() > 1) {
    // Several constant-current records separate the effects only if their currents differ.
    const double i0 = out.cases.front().excitation.typical_current_a;
    for (const auto& c : out.cases)
      if (std::abs(c.excitation.typical_current_a - i0) > 0.02 * st.imax) st.all_constant = false;
  }
  if (st.all_constant)
    out.excitation_note =
        "one constant current only: a contact resistance, hysteresis and a voltage offset, or a current-sensor "
        "offset and gain, leave the same residual and cannot be told apart";
  return st;
}

std::vector<Fold> make_folds(const std::vector<CaseResult>& cases, Fold& all) {
  const std::size_t nc = cases.size();
  std::vector<Fold> folds;
  all.train.assign(nc, {});
  all.validate.assign(nc, {});
  if (nc == 1) {
    folds.push_back({{cases[0].train}, {cases[0].validate}});
    all = folds.front();
    return folds;
  }
  for (std::size_t r = 0; r < nc; ++r) {
    Fold f;
    f.train.assign(nc, {});
    f.validate.assign(nc, {});
    for (std::size_t c = 0; c < nc; ++c) (c == r ? f.validate : f.train)[c] = cases[c].train;
    all.train[r] = cases[r].train;
    folds.push_back(std::move(f));
  }
  return folds;
}

// The plain model on both meshes: "before", the mesh correction and the floor.
void run_before(Context& ctx, DiagnosisResult& out) {
  Pool all, held;
  double floor2 = 0.0;
  std::size_t samples = 0;
  const auto& s = ctx.settings;
  // Every case's plain runs at once: the final mesh, the search mesh and, when the search
  // follows the drive in pieces, the search mesh on the exact drive (for the numerical error).
  const std::size_t nc = ctx.cases.size(), per_case = s.search_drive_tolerance > 0 ? 3 : 2;
  std::vector<std::vector<double>> plain(nc * per_case);
  for (const auto& cr : ctx.cases)
    ctx.say(fmt::format("{}: plain model, mesh {}/{} and {}/{}", cr.record->source, s.final_mesh.n_neg,
                        s.final_mesh.n_r, s.search_mesh.n_neg, s.search_mesh.n_r));
  parallel_for(plain.size(), ctx.threads, [&](std::size_t t) {
    const std::size_t c = t / per_case, kind = t % per_case;
    const Record& rec = *ctx.cases[c].record;
    if (kind == 0) {
      ModelRun run = run_model(ctx.eval.setup(true), rec, Hypothesis{});
      plain[t] = run.voltage_v;
      ctx.cases[c].before = std::move(run);
    } else if (kind == 1) {
      plain[t] = *ctx.eval.run(c, {}, false);
    } else {
      plain[t] = run_model(ModelSetup{ctx.eval.setup(false).cell, s.search_mesh, s.rtol}, rec, Hypothesis{}).voltage_v;
    }
  });
  for (std::size_t c = 0; c < nc; ++c) {
    auto& cr = ctx.cases[c];
    const Record& rec = *cr.record;
    ctx.eval.put(c, {}, true, cr.before.voltage_v);
    ctx.eval.put(c, {}, false, plain[c * per_case + 1]);
    const auto& coarse = plain[c * per_case + 1];
    std::vector<double> delta(coarse.size());
    for (std::size_t k = 0; k < delta.size(); ++k) delta[k] = cr.before.voltage_v[k] - coarse[k];
    // The mesh's own error from runs that differ only in the mesh (not in how the drive is followed).
    const double numerical =
        numerical_error_mv(cr.before.voltage_v, per_case > 2 ? plain[c * per_case + 2] : coarse, s.search_mesh.n_r,
                           s.final_mesh.n_r);
    ctx.eval.set_delta(c, std::move(delta));
    cr.residual_before_mv = residual_mv(cr.before.voltage_v, rec);
    cr.rmse_before_mv = rms(cr.residual_before_mv);
    cr.max_abs_before_mv = max_abs(cr.residual_before_mv);
    cr.heldout_before_mv = rms(cr.residual_before_mv, cr.validate);
    cr.char_before = characterise(rec, cr.residual_before_mv, cr.soc);
    cr.adequacy_before =
        check_adequacy(rec, cr.residual_before_mv, cr.char_before, measurement_noise_mv(rec), numerical);
    all.add(cr.residual_before_mv, {});
    held.add(cr.residual_before_mv, cr.validate);
    floor2 += std::pow(cr.adequacy_before.floor_mv, 2) * static_cast<double>(rec.t_s.size());
    samples += rec.t_s.size();
    ctx.say(fmt::format("{}: RMSE {:.3f} mV, max {:.3f} mV; {}", rec.source, cr.rmse_before_mv, cr.max_abs_before_mv,
                        cr.adequacy_before.verdict));
  }
  out.rmse_before_mv = all.rms();
  out.max_abs_before_mv = all.max_abs;
  out.heldout_before_mv = held.rms();
  out.floor_mv = std::sqrt(floor2 / static_cast<double>(std::max<std::size_t>(samples, 1)));
  out.at_floor_before = out.heldout_before_mv <= kFloorFactor * out.floor_mv;
  ctx.floor_mv = out.floor_mv;
}

struct Candidate {
  Effect effect;
  std::vector<Hypothesis> per_fold;
  Score score;
  double train_mv = 0.0;
  int evaluations = 0;
};

// An effect with a seed grid added to a base that has one: both grids searched together, then
// every knob fitted (the base's fit alone can sit in a basin the two together do not share).
FitResult fit_joined(Context& ctx, Hypothesis h, Effect e, const Fold& fold) {
  for (Effect k : knobs_of(e))
    if (!has_knob(h, k)) h.push_back({k, neutral_value(k)});
  const int runs = reseed_combination(ctx, h, fold);
  std::vector<Effect> knobs;
  for (const auto& s : h) knobs.push_back(s.effect);
  FitResult fit = fit_knobs(ctx, std::move(h), knobs, fold, true);
  fit.evaluations += runs;
  return fit;
}

// The candidate added to `base` (one hypothesis per fold), fitted per fold and scored.
Candidate try_candidate(Context& ctx, Effect e, const std::vector<Hypothesis>& base) {
  Candidate c{e, {}, {}, 0.0, 0};
  for (std::size_t f = 0; f < ctx.folds.size(); ++f) {
    const bool joined = has_seed_grid(e) && std::any_of(base[f].begin(), base[f].end(), [](const EffectSetting& s) {
                          return has_seed_grid(s.effect);
                        });
    auto fit = joined ? fit_joined(ctx, base[f], e, ctx.folds[f]) : fit_knobs(ctx, base[f], knobs_of(e), ctx.folds[f], false);
    c.train_mv += fit.train_mv / static_cast<double>(ctx.folds.size());
    c.evaluations += fit.evaluations;
    c.per_fold.push_back(std::move(fit.h));
  }
  c.score = score(ctx, c.per_fold);
  return c;
}

// Step 1: every candidate alone; the first effect is chosen by the selection rules (gain,
// ties, constant-current twins).
std::vector<Candidate> score_candidates(Context& ctx, DiagnosisResult& out, bool all_constant,
                                        const std::vector<Effect>& list, std::vector<Candidate> tried) {
  std::vector<CandidateScore> scores;
  for (const auto& c : tried) scores.push_back({c.effect, true, 0.0, c.score.heldout_mv});
  const std::vector<Hypothesis> empty(ctx.folds.size());
  // Every available candidate fitted and scored at once (independent of each other), then
  // reported in the list's order.
  std::vector<Candidate> fitted(list.size(), Candidate{Effect::none, {}, {}, 0.0, 0});
  parallel_for(list.size(), ctx.threads, [&](std::size_t i) {
    if (effect_available(list[i])) fitted[i] = try_candidate(ctx, list[i], empty);
  });
  for (std::size_t i = 0; i < list.size(); ++i) {
    const Effect e = list[i];
    CandidateResult cand;
    cand.effect = e;
    cand.available = effect_available(e);
    if (!cand.available) {
      cand.note = "not in this build's truth model";
      out.candidates.push_back(cand);
      continue;
    }
    Candidate& c = fitted[i];
    cand.fitted = c.per_fold.front();
    cand.value = knob_value(cand.fitted, e);
    cand.train_rmse_mv = c.train_mv;
    cand.heldout_rmse_mv = c.score.heldout_mv;
    cand.rmse_after_mv = c.score.all_mv;
    cand.max_abs_after_mv = c.score.max_abs_mv;
    cand.evaluations = c.evaluations;
    if (c.score.failed) {
      cand.available = false;
      cand.note = "the model failed on the final mesh with the fitted value";
    }
    ctx.say(fmt::format("step 1, candidate {}/{} {}: {}: held-out RMSE {:.3f} mV (plain {:.3f}), {} evaluations",
                        i + 1, list.size(), effect_name(e), knob_list(cand.fitted), cand.heldout_rmse_mv,
                        out.heldout_before_mv, cand.evaluations));
    scores.push_back({e, cand.available, cand.value, cand.heldout_rmse_mv});
    out.candidates.push_back(cand);
    if (cand.available) tried.push_back(std::move(c));
  }
  ctx.say(fmt::format("step 1: {} model runs so far", ctx.eval.runs()));
  SelectionRules rules = ctx.settings.rules;
  rules.constant_current_only = all_constant;
  rules.floor_mv = out.floor_mv;
  out.selection = select_effect(out.heldout_before_mv, scores, rules);
  SelectionStep step;
  for (const auto& c : tried) step.scores.emplace_back(c.effect, c.score.heldout_mv);
  step.chosen = out.selection.effect;
  step.reason = out.selection.reason;
  out.steps.push_back(step);
  return tried;
}

// Steps 2..max_effects from one first effect: each remaining candidate added to the effects so
// far; the best is kept if it cuts the held-out RMSE by the complexity penalty, then all knobs
// are refined together. `tried` is sorted by held-out RMSE.
Candidate grow_combination(Context& ctx, DiagnosisResult& out, const std::vector<Candidate>& tried, Effect first) {
  Candidate current{Effect::none, std::vector<Hypothesis>(ctx.folds.size()), {}, 0.0, 0};
  const auto& s = ctx.settings;
  for (const auto& c : tried)
    if (c.effect == first) current = c;
  out.effects = {current.effect};
  while (static_cast<int>(out.effects.size()) < s.max_effects &&
         current.score.heldout_mv > kFloorFactor * out.floor_mv) {
    SelectionStep step;
    step.base = out.effects;
    Candidate best{Effect::none, {}, {}, 0.0, 0};
    best.score.heldout_mv = HUGE_VAL;
    std::vector<Effect> remaining;
    for (const auto& t : tried)
      if (std::find(out.effects.begin(), out.effects.end(), t.effect) == out.effects.end()) remaining.push_back(t.effect);
    std::vector<Candidate> added(remaining.size(), Candidate{Effect::none, {}, {}, 0.0, 0});
    parallel_for(remaining.size(), ctx.threads,
                 [&](std::size_t i) { added[i] = try_candidate(ctx, remaining[i], current.per_fold); });
    for (auto& c : added) {
      step.scores.emplace_back(c.effect, c.score.heldout_mv);
      ctx.say(fmt::format("step {}, {} + {}: held-out RMSE {:.3f} mV (now {:.3f}), {} evaluations", out.steps.size() + 1,
                          effect_list(out.effects), effect_name(c.effect), c.score.heldout_mv, current.score.heldout_mv,
                          c.evaluations));
      if (c.score.heldout_mv < best.score.heldout_mv) best = std::move(c);
    }
    const double gain = current.score.heldout_mv - best.score.heldout_mv;
    if (best.effect == Effect::none || gain < s.further_gain * current.score.heldout_mv ||
        gain < s.rules.min_absolute_gain_mv) {
      step.reason = best.effect == Effect::none
                        ? "no candidate left"
                        : fmt::format("best addition {} cuts the held-out RMSE by {:.3f} mV only (needs {:.0f} % of "
                                      "{:.3f} mV and {:.2f} mV): stop",
                                      effect_name(best.effect), gain, 100 * s.further_gain, current.score.heldout_mv,
                                      s.rules.min_absolute_gain_mv);
      out.steps.push_back(step);
      break;
    }
    // Refine every knob together (narrow coordinate search) and keep it if it helps.
    const auto knobs = effects_in(out.effects, best.effect);
    Candidate refined = best;
    refined.per_fold.clear();
    for (std::size_t f = 0; f < ctx.folds.size(); ++f)
      refined.per_fold.push_back(fit_knobs(ctx, best.per_fold[f], knobs, ctx.folds[f], true).h);
    refined.score = score(ctx, refined.per_fold);
    if (refined.score.heldout_mv < best.score.heldout_mv) best = std::move(refined);
    step.chosen = best.effect;
    step.reason = fmt::format("{} cuts the held-out RMSE from {:.3f} to {:.3f} mV", effect_name(best.effect),
                              current.score.heldout_mv, best.score.heldout_mv);
    out.steps.push_back(step);
    out.effects.push_back(best.effect);
    current = std::move(best);
  }
  return current;
}

// A first effect too weak to be named alone may still open a combination that explains the
// residual; a tie or a twin may not (the combination would name a guess). Such combinations are
// grown from the best `beam` single effects that open one: two effects that help only together
// (a knee-shaped cathode resistance and self-heating, each alone near the plain model) are not
// found from a better single effect. Another start's path replaces the best single's only when
// it cuts the held-out RMSE by the complexity penalty.
Candidate forward_selection(Context& ctx, DiagnosisResult& out, std::vector<Candidate> tried) {
  Candidate none{Effect::none, std::vector<Hypothesis>(ctx.folds.size()), {}, 0.0, 0};
  none.score.heldout_mv = out.heldout_before_mv;
  out.effects.clear();
  const auto& s = ctx.settings;
  const auto opens = [&](const Candidate& c) {
    return out.heldout_before_mv - c.score.heldout_mv >=
           std::max(s.open_gain * out.heldout_before_mv, s.open_gain > 0 ? s.rules.min_absolute_gain_mv : -HUGE_VAL);
  };
  std::sort(tried.begin(), tried.end(), [](auto& a, auto& b) { return a.score.heldout_mv < b.score.heldout_mv; });
  std::vector<Effect> starts;
  if (out.selection.effect != Effect::none) {
    starts.push_back(out.selection.effect);
  } else if (out.selection.identifiable) {
    for (const auto& c : tried)
      if (c.effect == out.selection.best && opens(c)) starts.push_back(c.effect);
    for (const auto& c : tried)
      if (!starts.empty() && static_cast<int>(starts.size()) < s.beam && c.effect != starts.front() && opens(c))
        starts.push_back(c.effect);
  }
  if (starts.empty()) return none;
  DiagnosisResult chosen_out = out;
  Candidate chosen = grow_combination(ctx, chosen_out, tried, starts.front());
  for (std::size_t i = 1; i < starts.size(); ++i) {
    DiagnosisResult path_out = out;
    Candidate path = grow_combination(ctx, path_out, tried, starts[i]);
    const double gain = chosen.score.heldout_mv - path.score.heldout_mv;
    const bool better = gain >= s.further_gain * chosen.score.heldout_mv && gain >= s.rules.min_absolute_gain_mv;
    ctx.say(fmt::format("combination from {}: {} at {:.3f} mV held out, against {} at {:.3f} mV: {}",
                        effect_name(starts[i]), effect_list(path_out.effects), path.score.heldout_mv,
                        effect_list(chosen_out.effects), chosen.score.heldout_mv, better ? "taken" : "not taken"));
    if (better) {
      chosen_out = std::move(path_out);
      chosen = std::move(path);
    }
  }
  out = std::move(chosen_out);
  return chosen;
}

// The chosen effects fitted on all the data (one record: its training blocks) give "after";
// the held-out numbers per case come from the folds.
void fit_all_and_after(Context& ctx, DiagnosisResult& out, const Candidate& best) {
  Hypothesis h = best.per_fold.empty() ? Hypothesis{} : best.per_fold.front();
  if (ctx.folds.size() > 1 && !out.effects.empty())
    h = fit_knobs(ctx, h, effects_in(out.effects, Effect::none), ctx.all, true).h;
  out.model = h;
  out.heldout_after_mv = best.score.heldout_mv;
  Pool all, held;
  for (std::size_t c = 0; c < ctx.cases.size(); ++c) {
    auto& cr = ctx.cases[c];
    const Record& rec = *cr.record;
    cr.after = cr.before;
    cr.after.voltage_v = ctx.eval.voltage(c, h, true);
    cr.residual_after_mv = residual_mv(cr.after.voltage_v, rec);
    cr.rmse_after_mv = rms(cr.residual_after_mv);
    cr.max_abs_after_mv = max_abs(cr.residual_after_mv);
    cr.char_after = characterise(rec, cr.residual_after_mv, cr.soc);
    cr.adequacy_after = check_adequacy(rec, cr.residual_after_mv, cr.char_after, cr.adequacy_before.noise_mv,
                                       cr.adequacy_before.numerical_mv);
    const std::size_t f = ctx.folds.size() > 1 ? c : 0;
    const auto held_r = best.per_fold.empty() ? cr.residual_before_mv : ctx.eval.residual(c, best.per_fold[f], true);
    cr.heldout_after_mv = rms(held_r, cr.validate);
    all.add(cr.residual_after_mv, {});
  }
  out.rmse_after_mv = all.rms();
  out.max_abs_after_mv = all.max_abs;
}

// The Fisher information J^T J / sigma^2 of a few knobs and its pseudo-inverse.

SmallMatrix fisher_pseudo_inverse(const std::vector<std::vector<double>>& columns, double sigma) {
  const auto p = static_cast<Eigen::Index>(columns.size());
  SmallMatrix fisher(p, p);
  for (Eigen::Index a = 0; a < p; ++a)
    for (Eigen::Index b = 0; b <= a; ++b) {
      double dot = 0.0;
      const auto& ca = columns[static_cast<std::size_t>(a)];
      const auto& cb = columns[static_cast<std::size_t>(b)];
      for (std::size_t i = 0; i < std::min(ca.size(), cb.size()); ++i) dot += ca[i] * cb[i];
      fisher(a, b) = fisher(b, a) = dot / (sigma * sigma);
    }
  const Eigen::SelfAdjointEigenSolver<SmallMatrix> eig(fisher);
  const auto& lambda = eig.eigenvalues();
  const double tol = 1e-12 * std::max(lambda.cwiseAbs().maxCoeff(), 1e-300);
  SmallMatrix inv_lambda = SmallMatrix::Zero(p, p);
  for (Eigen::Index k = 0; k < p; ++k)
    if (lambda(k) > tol) inv_lambda(k, k) = 1.0 / lambda(k);
  return eig.eigenvectors() * inv_lambda * eig.eigenvectors().transpose();
}

// Sensitivity of the model voltage to every candidate knob at the fitted model, and the
// Fisher information of the selected ones: J^T J / sigma^2 with sigma = the floor.
void identifiability(Context& ctx, DiagnosisResult& out) {
  std::vector<Effect> knobs = effects_in(out.effects, Effect::none);
  const std::size_t n_selected = knobs.size();
  for (Effect e : ctx.settings.candidates)
    for (Effect k : knobs_of(e))
      if (effect_available(k) && std::find(knobs.begin(), knobs.end(), k) == knobs.end()) knobs.push_back(k);
  std::vector<std::vector<double>> base(ctx.cases.size());
  for (std::size_t c = 0; c < ctx.cases.size(); ++c) base[c] = ctx.eval.voltage(c, out.model, false);
  // One forward difference per knob, every knob at once; a knob whose run fails is left out.
  std::vector<std::vector<double>> knob_columns(knobs.size());
  std::vector<char> knob_ok(knobs.size(), 0);
  parallel_for(knobs.size(), ctx.threads, [&](std::size_t j) {
    const Effect k = knobs[j];
    const SearchSpace sp = search_space(k, ctx.imax, ctx.dt_s);
    Hypothesis h = out.model;
    if (!has_knob(h, k)) h.push_back({k, neutral_value(k)});
    if (k == Effect::rc_time_constant && knob_value(h, Effect::rc_branch) == 0.0) set_knob(h, Effect::rc_branch, 0.005);
    if (k == Effect::diffusivity_profile_knee && knob_value(h, Effect::diffusivity_profile_positive) == 0.0)
      set_knob(h, Effect::diffusivity_profile_positive, -1.0);
    if ((k == Effect::resistive_reactant_log10 || k == Effect::resistive_reactant_knee) &&
        knob_value(h, Effect::resistive_reactant_positive) == 0.0)
      set_knob(h, Effect::resistive_reactant_positive, 0.1);
    const double x0 = std::clamp(sp.x_of(knob_value(h, k)), sp.lo, sp.hi);
    const double dx = 0.01 * (sp.hi - sp.lo) * (x0 + 0.01 * (sp.hi - sp.lo) > sp.hi ? -1.0 : 1.0);
    set_knob(h, k, sp.value(x0 + dx));
    std::vector<double> col;
    try {
      for (std::size_t c = 0; c < ctx.cases.size(); ++c) {
        const auto v = ctx.eval.voltage(c, h, false);
        for (std::size_t i = 0; i < v.size(); ++i)
          col.push_back(std::isfinite(v[i]) && std::isfinite(base[c][i]) ? 1e3 * (v[i] - base[c][i]) / dx : 0.0);
      }
    } catch (const RuntimeFailure&) {
      return;
    }
    knob_columns[j] = std::move(col);
    knob_ok[j] = 1;
  });
  std::vector<std::vector<double>> columns;
  for (std::size_t j = 0; j < knobs.size(); ++j) {
    if (!knob_ok[j]) continue;
    const Effect k = knobs[j];
    std::vector<double>& col = knob_columns[j];
    KnobIdentifiability ki;
    ki.knob = k;
    ki.value = knob_value(out.model, k, neutral_value(k));
    ki.selected = out.identifiability.size() < n_selected;
    double sum_sq = 0.0;
    for (double x : col) sum_sq += x * x;
    ki.sensitivity_mv = std::sqrt(sum_sq / static_cast<double>(std::max<std::size_t>(col.size(), 1)));
    if (ki.selected && columns.size() < kMaxFisherKnobs) columns.push_back(std::move(col));
    out.identifiability.push_back(ki);
  }
  if (columns.empty()) return;
  const double sigma = std::max(out.floor_mv, 0.01);
  const SmallMatrix cov = fisher_pseudo_inverse(columns, sigma);
  for (std::size_t k = 0; k < columns.size(); ++k) {
    auto& ki = out.identifiability[k];
    const auto i = static_cast<Eigen::Index>(k);
    ki.std_error = std::sqrt(std::max(cov(i, i), 0.0));
    const SearchSpace sp = search_space(ki.knob, ctx.imax, ctx.dt_s);
    ki.relative_std_pct = sp.log10 ? 100.0 * (std::pow(10.0, ki.std_error) - 1.0)
                                   : (ki.value != 0.0 ? 100.0 * ki.std_error / std::abs(ki.value) : HUGE_VAL);
    for (std::size_t m = 0; m < columns.size(); ++m) {
      const auto jdx = static_cast<Eigen::Index>(m);
      if (m != k && cov(i, i) > 0 && cov(jdx, jdx) > 0)
        ki.max_abs_correlation = std::max(ki.max_abs_correlation, std::abs(cov(i, jdx)) / std::sqrt(cov(i, i) * cov(jdx, jdx)));
    }
  }
  std::sort(out.identifiability.begin() + static_cast<std::ptrdiff_t>(columns.size()), out.identifiability.end(),
            [](const auto& a, const auto& b) { return a.sensitivity_mv > b.sensitivity_mv; });
}

// The answer: the effects if they explain the residual on held-out data, none when the
// residual was at its floor anyway, unexplained otherwise (the best model reached is kept as a
// partial result, never as the answer).
void decide(DiagnosisResult& out, const DiagnoseSettings& s) {
  const double share = out.heldout_before_mv > 0 ? out.heldout_after_mv / out.heldout_before_mv : 1.0;
  out.explained = !out.effects.empty() && share <= s.explained_share;
  if (out.explained) {
    out.answer = out.effects.front();
    out.reason = fmt::format("{} ({}) bring the held-out RMSE from {:.3f} to {:.3f} mV ({:.0f} %). {}",
                             effect_list(out.effects), knob_list(out.model), out.heldout_before_mv,
                             out.heldout_after_mv, 100 * share, out.selection.reason);
    return;
  }
  out.best_partial = out.model;
  out.best_partial_effects = out.effects;
  out.best_partial_heldout_mv = out.heldout_after_mv;
  std::string residual;
  for (const auto& c : out.cases) residual += fmt::format(" [{}: {}]", c.record->source, c.adequacy_before.verdict);
  if (out.at_floor_before) {
    out.answer = Effect::none;
    out.reason = fmt::format("the residual is at its floor: held-out RMSE {:.3f} mV <= {:g} x {:.3f} mV (voltage noise "
                             "and the model's numerical error). {}",
                             out.heldout_before_mv, kFloorFactor, out.floor_mv, out.selection.reason);
  } else {
    out.answer = Effect::unexplained;
    out.reason = fmt::format(
        "no candidate or combination of up to {} brings the held-out RMSE to {:.0f} % of {:.3f} mV (best reached: {}, "
        "{:.3f} mV = {:.0f} %; {}). First step: {}. The residual:{}",
        s.max_effects, 100 * s.explained_share, out.heldout_before_mv, effect_list(out.effects), out.heldout_after_mv,
        100 * share, knob_list(out.model), out.selection.reason, residual);
  }
  out.effects.clear();
  out.model.clear();
}

// Candidates the cell cannot take (the lumped thermal model needs a heat capacity, hysteresis a
// nominal capacity) are reported as unavailable instead of failing every run that tries them.
std::vector<CandidateResult> drop_unusable(const CellParameters& cell, std::vector<Effect>& candidates) {
  std::vector<CandidateResult> dropped;
  const auto& th = cell.thermal;
  for (auto it = candidates.begin(); it != candidates.end();) {
    std::string why;
    if (*it == Effect::thermal && !(th.specific_heat_j_kg_k * th.density_kg_m3 * th.volume_m3 > 0.0))
      why = "the cell has no heat capacity (BPX Cell: specific heat capacity, density, volume)";
    if (*it == Effect::hysteresis && !(cell.nominal_capacity_ah > 0.0)) why = "the cell has no nominal capacity";
    if (why.empty()) {
      ++it;
      continue;
    }
    CandidateResult c;
    c.effect = *it;
    c.available = false;
    c.note = why;
    dropped.push_back(c);
    it = candidates.erase(it);
  }
  return dropped;
}

}  // namespace

DiagnosisResult diagnose(const CellParameters& cell, const std::vector<Record>& records,
                         const DiagnoseSettings& settings_in, const LogFn& log) {
  DiagnoseSettings settings = settings_in;
  const std::vector<CandidateResult> unusable = drop_unusable(cell, settings.candidates);
  const auto wall0 = std::chrono::steady_clock::now();
  auto elapsed = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count(); };
  auto say = [&](const std::string& s) {
    if (log) log(fmt::format("[{:6.1f} s] {}", elapsed(), s));
  };
  if (records.empty()) throw InputError("--data: no record given");
  DiagnosisResult out;
  const Setup st = build_cases(cell, records, settings, out, say);
  Evaluator eval(out.cases, ModelSetup{cell, settings.search_mesh, settings.rtol, settings.search_drive_tolerance},
                 ModelSetup{cell, settings.final_mesh, settings.rtol});
  Context ctx{settings, out.cases, eval, {}, {}, st.imax, st.dt_s, say, 0.0, thread_count(settings.threads)};
  ctx.folds = make_folds(out.cases, ctx.all);
  run_before(ctx, out);
  CandidateResult none;
  none.heldout_rmse_mv = out.heldout_before_mv;
  none.rmse_after_mv = out.rmse_before_mv;
  none.max_abs_after_mv = out.max_abs_before_mv;
  out.candidates.push_back(none);
  for (const auto& c : unusable) {
    say(fmt::format("candidate {}: not available: {}", effect_name(c.effect), c.note));
    out.candidates.push_back(c);
  }
  if (st.all_rest || out.at_floor_before) {
    // At the floor no candidate can bring the held-out RMSE to 20 % of it (the noise stays):
    // the answer is none whatever the candidates do, so none is run.
    out.selection.reason = st.all_rest ? "no current flows in the data: no effect can be identified"
                                       : "the plain model is already at the residual's floor: no candidate searched";
    say(out.selection.reason);
    Candidate plain{Effect::none, {}, {}, 0.0, 0};
    plain.score.heldout_mv = out.heldout_before_mv;
    fit_all_and_after(ctx, out, plain);
  } else {
    // Tier 1: sensor, wiring and structural effects. Tier 2 adds the re-fits of the cell's
    // own parameters (and its start state) only when tier 1 does not explain the residual: the
    // more specific explanation first, and a re-fit can mimic a sensor or wiring fault.
    std::vector<Effect> tier1, tier2;
    for (Effect e : settings.candidates)
      (knob_kind(e) == KnobKind::parameter || e == Effect::initial_soc || e == Effect::diffusivity_profile_positive ||
               e == Effect::resistive_reactant_positive
           ? tier2
           : tier1)
          .push_back(e);
    auto tried = score_candidates(ctx, out, st.all_constant, tier1, {});
    Candidate best = forward_selection(ctx, out, tried);
    if (!tier2.empty() && best.score.heldout_mv > settings.explained_share * out.heldout_before_mv) {
      say("tier 1 does not explain the residual: tier 2, the cell's parameters re-fitted");
      tried = score_candidates(ctx, out, st.all_constant, tier2, std::move(tried));
      best = forward_selection(ctx, out, tried);
    }
    fit_all_and_after(ctx, out, best);
    say("sensitivities and Fisher information at the fitted model");
    identifiability(ctx, out);
  }
  if (out.selection.effect == Effect::none && !out.excitation_note.empty() &&
      out.selection.reason.find("constant current") == std::string::npos)
    out.selection.reason += " (" + out.excitation_note + ")";
  decide(out, settings);
  out.runs = eval.runs();
  out.wall_s = elapsed();
  say(fmt::format("diagnosis: {} ({} model runs)", effect_name(out.answer), out.runs));
  return out;
}

}  // namespace bms::diagnosis
