#include "diagnosis/cell_fit.hpp"

#include <fmt/format.h>

#include <Eigen/Dense>
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>

#include "diagnosis/diagnose.hpp"
#include "diagnosis/model_run.hpp"
#include "diagnosis/normal_equations.hpp"
#include "io/bpx_reader.hpp"
#include "io/bpx_writer.hpp"
#include "io/input_error.hpp"
#include "io/table_function.hpp"

namespace bms::diagnosis {

namespace {

constexpr double kStoichEdge = 1e-3;

// One parameter fit may move. Log knobs: z = ln(value / template value); the x100 knob: z = value;
// the open-circuit correction's knots (after the named knobs): z = the correction in volts.
enum class Knob {
  electrode_area,
  positive_capacity,
  negative_stoich_full,
  series_film,
  diffusivity_negative,
  diffusivity_positive,
  rate_negative,
  rate_positive,
  conductivity,
};
constexpr int kNamedKnobs = 9;
constexpr int kKnobs = kNamedKnobs + kMaxOcpKnots;
constexpr int kFirstKnot = kNamedKnobs;
bool is_knot(int k) { return k >= kFirstKnot; }
// Bounded sizes throughout: the host links the firmware's EIGEN_NO_MALLOC, so no Eigen object
// here may allocate. z holds every knob; the Jacobian is columns of std::vector (one a knob).
using ZVec = Eigen::Matrix<double, kKnobs, 1>;
using SmallMatrix = BoundedMatrix<kKnobs>;
using SmallVector = BoundedVector<kKnobs>;

// The pseudo-inverse of a symmetric positive semi-definite matrix (eigenvalues under 1e-12 of the
// largest taken as zero).
SmallMatrix pseudo_inverse(const SmallMatrix& h) {
  const Eigen::SelfAdjointEigenSolver<SmallMatrix> eig(h);
  const auto& lambda = eig.eigenvalues();
  const Eigen::Index n = h.rows();
  const double tol = 1e-12 * std::max(n > 0 ? lambda.cwiseAbs().maxCoeff() : 0.0, 1e-300);
  SmallMatrix inv = SmallMatrix::Zero(n, n);
  for (Eigen::Index k = 0; k < n; ++k)
    if (lambda(k) > tol) inv(k, k) = 1.0 / lambda(k);
  return eig.eigenvectors() * inv * eig.eigenvectors().transpose();
}

struct KnobInfo {
  const char* name;
  const char* unit;
  const char* meaning;
  bool log;
  double lo, hi;  // bounds on z (log knobs: relative to the template)
  double step;    // finite-difference step in z
  double max_move;  // largest change of z per iteration
};

const KnobInfo& info(Knob k) {
  static const std::array<std::string, kMaxOcpKnots> knot_names = [] {
    std::array<std::string, kMaxOcpKnots> n;
    for (int i = 0; i < kMaxOcpKnots; ++i) n[static_cast<std::size_t>(i)] = fmt::format("ocp_correction_{}", i + 1);
    return n;
  }();
  static const std::array<KnobInfo, kKnobs> table = [] {
    std::array<KnobInfo, kKnobs> t{{
      {"electrode_area_m2", "m2", "Cell.Electrode area: both electrodes' capacity (and every resistance per area)",
       true, std::log(0.3), std::log(4.0), 0.01, 0.3},
      {"positive_max_concentration_mol_m3", "mol/m3",
       "Positive electrode.Maximum concentration: the positive electrode's capacity against the negative's", true,
       std::log(0.5), std::log(2.0), 0.01, 0.3},
      {"negative_stoichiometry_full", "-",
       "Negative electrode.Maximum stoichiometry: the negative electrode's state at the upper voltage (with the "
       "positive's there, the cell's lithium inventory)",
       false, 0.3, 0.999, 0.002, 0.05},
      {"initial_sei_resistance_ohm_m2", "ohm m2",
       "User-defined.Initial SEI resistance: a series resistance on the negative particles' surface (the film the "
       "estimator learns)",
       true, std::log(1e-3), std::log(1e3), 0.05, 1.5},
      {"negative_diffusivity_m2_s", "m2/s", "Negative electrode.Diffusivity (solid)", true, std::log(1e-3),
       std::log(1e3), 0.08, 1.5},
      {"positive_diffusivity_m2_s", "m2/s", "Positive electrode.Diffusivity (solid)", true, std::log(1e-3),
       std::log(1e3), 0.08, 1.5},
      {"negative_rate_constant_mol_m2_s", "mol/m2/s", "Negative electrode.Reaction rate constant (kinetics)", true,
       std::log(1e-3), std::log(1e3), 0.08, 1.5},
      {"positive_rate_constant_mol_m2_s", "mol/m2/s", "Positive electrode.Reaction rate constant (kinetics)", true,
       std::log(1e-3), std::log(1e3), 0.08, 1.5},
      {"electrolyte_conductivity_scale", "-", "Electrolyte.Conductivity: factor on kappa(c_e)", true, std::log(0.05),
       std::log(20.0), 0.08, 1.5},
  }};
    for (int i = 0; i < kMaxOcpKnots; ++i)
      t[static_cast<std::size_t>(kFirstKnot + i)] = {
          knot_names[static_cast<std::size_t>(i)].c_str(), "V",
          "Positive electrode.OCP: additive correction at this knot (piecewise linear in the positive "
          "stoichiometry between knots, constant beyond the end knots)",
          false, -0.3, 0.3, 0.005, 0.05};
    return t;
  }();
  return table[static_cast<std::size_t>(k)];
}

double electrode_capacity_ah(const CellParameters& cell, const ElectrodeParameters& e) {
  return kFaradayC_mol * cell.electrode_area_m2 * e.thickness_m * e.solid_fraction * e.max_concentration_mol_m3 /
         3600.0;
}

// f(a) < 0 < f(b): the root's bracket end where f > 0 (the balance's f > 0 is inside the window,
// so the cell's full and empty states never lie a rounding error outside it).
double bisect(const std::function<double(double)>& f, double a, double b) {
  for (int it = 0; it < 200 && b - a > 1e-13; ++it) {
    const double m = 0.5 * (a + b);
    (f(m) < 0 ? a : b) = m;
  }
  return b;
}

struct Balance {
  bool ok = false;
  double x0 = 0, x100 = 0, y0 = 0, y100 = 0, capacity_ah = 0;
};

// The electrode balance at the voltage window for electrode capacities qn, qp (Ah) and the
// negative stoichiometry x100 at v_max; `correction` (if any) is added to the positive's OCP.
Balance balance(const CellParameters& c, double qn, double qp, double x100, double v_min, double v_max,
                const ScalarFunction* correction = nullptr) {
  Balance b;
  auto un = [&](double x) { return c.negative.ocp_v->value(x); };
  auto up = [&](double y) { return c.positive.ocp_v->value(y) + (correction ? correction->value(y) : 0.0); };
  const double target = v_max + un(x100);
  auto fy = [&](double y) { return target - up(y); };  // up falls with y
  const double ylo = kStoichEdge, yhi = 1.0 - kStoichEdge;
  if (!(fy(ylo) < 0 && fy(yhi) > 0)) return b;
  b.y100 = bisect(fy, ylo, yhi);
  b.x100 = x100;
  const double n = x100 * qn + b.y100 * qp;
  auto fx = [&](double x) { return up((n - x * qn) / qp) - un(x) - v_min; };  // rises with x
  const double xlo = std::max(kStoichEdge, (n - yhi * qp) / qn);
  if (!(xlo < x100) || !(fx(xlo) < 0)) return b;
  b.x0 = bisect(fx, xlo, x100);
  b.y0 = (n - b.x0 * qn) / qp;
  b.capacity_ah = (x100 - b.x0) * qn;
  b.ok = std::isfinite(b.capacity_ah) && b.capacity_ah > 0;
  return b;
}

// The piecewise-linear function through (x_k, y_k), constant beyond the ends, as a BPX expression
// (exactly: c + sum_k w_k |x - x_k| with w_k half the change of slope at knot k).
std::string piecewise_linear_expression(const std::vector<double>& x, const std::vector<double>& y) {
  const std::size_t n = x.size();
  std::vector<double> slope(n + 1, 0.0);  // slope[k]: left of knot k; slope[n]: right of the last
  for (std::size_t k = 1; k < n; ++k) slope[k] = (y[k] - y[k - 1]) / (x[k] - x[k - 1]);
  double c = y[0];
  std::string terms;
  for (std::size_t k = 0; k < n; ++k) {
    const double w = 0.5 * (slope[k + 1] - slope[k]);
    c -= w * (x[k] - x[0]);
    terms += fmt::format(" + ({:.17g}) * abs(x - {:.17g})", w, x[k]);
  }
  return fmt::format("({:.17g}){}", c, terms);
}

// The template's OCP (a number, an expression or a table) plus the correction, exactly: a table
// on the union of its points and the knots, otherwise an expression.
void add_ocp_correction(nlohmann::json& v, const TableFunction& correction) {
  const std::string corr = piecewise_linear_expression(correction.x(), correction.y());
  if (v.is_number()) {
    v = fmt::format("{:.17g} + {}", v.get<double>(), corr);
  } else if (v.is_string()) {
    v = fmt::format("({}) + {}", v.get<std::string>(), corr);
  } else if (v.is_object() && v.contains("x") && v.contains("y")) {
    const TableFunction base(v["x"].get<std::vector<double>>(), v["y"].get<std::vector<double>>(), "template OCP");
    std::vector<double> xs = base.x();
    xs.insert(xs.end(), correction.x().begin(), correction.x().end());
    std::sort(xs.begin(), xs.end());
    xs.erase(std::unique(xs.begin(), xs.end()), xs.end());
    std::vector<double> ys;
    for (double x : xs) ys.push_back(base.value(x) + correction.value(x));
    v = {{"x", xs}, {"y", ys}};
  } else {
    throw InputError("template: field 'Positive electrode.OCP [V]' is neither a number, an expression nor a table");
  }
}

class Problem {
 public:
  Problem(const nlohmann::json& tmpl, const std::string& name, const std::vector<FitPiece>& pieces,
          const CellFitSettings& s)
      : tmpl_(tmpl), name_(name), pieces_(pieces), s_(s) {
    base_ = read_bpx_text(tmpl_.dump(), name + " (template)");
    qn0_ = electrode_capacity_ah(base_, base_.negative);
    qp0_ = electrode_capacity_ah(base_, base_.positive);
    // The template's lithium inventory, at the fitted cell's upper voltage.
    const double n0 = base_.negative.stoich_max * qn0_ + base_.positive.stoich_min * qp0_;
    auto f = [&](double x) {
      return base_.positive.ocp_v->value((n0 - x * qn0_) / qp0_) - base_.negative.ocp_v->value(x) - s_.v_max;
    };
    const double lo = std::max(kStoichEdge, (n0 - (1 - kStoichEdge) * qp0_) / qn0_);
    const double hi = std::min(1 - kStoichEdge, (n0 - kStoichEdge * qp0_) / qn0_);
    if (std::abs(s_.v_max - base_.upper_voltage_v) < 1e-9) {
      x100_0_ = base_.negative.stoich_max;
    } else if (f(lo) < 0 && f(hi) > 0) {
      x100_0_ = bisect(f, lo, hi);
    } else {
      // The template's lithium cannot reach the data's upper voltage: start from its negative
      // electrode's full state instead (the positive's state there follows from the voltage).
      x100_0_ = base_.negative.stoich_max;
      notes_.push_back(fmt::format("the template's lithium inventory does not reach {:.3f} V: the start keeps its "
                                   "negative electrode's full stoichiometry {:.5f} and takes the positive's from the "
                                   "voltage",
                                   s_.v_max, x100_0_));
    }
    Balance check = balance(base_, qn0_, qp0_, x100_0_, s_.v_min, s_.v_max);
    if (!check.ok)
      throw InputError(fmt::format("--template {}: its open-circuit curves have no state at the data's voltage "
                                   "window {:.3f}-{:.3f} V; give --template a cell for this chemistry",
                                   name, s_.v_min, s_.v_max));
    // The correction's knots: evenly over the positive's window of the template at the data's voltages.
    if (s_.ocp_knots >= 2) {
      const nlohmann::json& ocp = tmpl_.at("Parameterisation").at("Positive electrode").value("OCP [V]", nlohmann::json());
      if (!(ocp.is_number() || ocp.is_string() || (ocp.is_object() && ocp.contains("x") && ocp.contains("y"))))
        throw InputError("--ocp-knots: the template has no 'Positive electrode.OCP [V]' number, expression or table "
                         "to correct");
      for (int i = 0; i < s_.ocp_knots; ++i)
        knot_y_.push_back(check.y100 + (check.y0 - check.y100) * i / (s_.ocp_knots - 1));
    }
    template_values_ = {
        bpx_number(bpx_field(tmpl_, "Cell", "Electrode area [m2]"), "Cell.Electrode area [m2]"),
        bpx_number(bpx_field(tmpl_, "Positive electrode", "Maximum concentration [mol.m-3]"),
                  "Positive electrode.Maximum concentration [mol.m-3]"),
        x100_0_,
        base_.side.initial_film_resistance_ohm_m2,
        base_.negative.solid_diffusivity_m2_s,
        base_.positive.solid_diffusivity_m2_s,
        number_or_nan("Negative electrode", "Reaction rate constant [mol.m-2.s-1]"),
        number_or_nan("Positive electrode", "Reaction rate constant [mol.m-2.s-1]"),
        1.0};
    template_values_.resize(kKnobs, 0.0);  // the open-circuit correction: none
    if (!base_.side.enabled) notes_.push_back("the template has no side reaction: the series film is not fitted");
  }

  // The template (its parameters in the data's voltage window).
  ZVec z0() const {
    ZVec z = ZVec::Zero();
    z[static_cast<int>(Knob::negative_stoich_full)] = x100_0_;
    return z;
  }
  // Where the search starts: the template with its area scaled to the measured capacity.
  ZVec start() const {
    ZVec z = z0();
    if (s_.measured_capacity_ah > 0) {
      Balance b = balance(base_, qn0_, qp0_, x100_0_, s_.v_min, s_.v_max);
      const KnobInfo& a = info(Knob::electrode_area);
      z[static_cast<int>(Knob::electrode_area)] = std::clamp(std::log(s_.measured_capacity_ah / b.capacity_ah), a.lo, a.hi);
    }
    return z;
  }
  double template_value(int k) const { return template_values_[static_cast<std::size_t>(k)]; }
  double value(int k, double z) const { return info(static_cast<Knob>(k)).log ? template_value(k) * std::exp(z) : z; }
  const std::vector<std::string>& notes() const { return notes_; }
  const CellParameters& base() const { return base_; }
  bool has_film() const { return base_.side.enabled; }
  int knot_count() const { return static_cast<int>(knot_y_.size()); }
  double knot_y(int i) const { return knot_y_[static_cast<std::size_t>(i)]; }

  // The candidate cell as BPX JSON; ok = false when the electrode balance has no solution.
  nlohmann::json bpx(const ZVec& z, Balance& b) const {
    nlohmann::json j = tmpl_;
    auto f = [&](Knob k) { return std::exp(z[static_cast<int>(k)]); };
    scale_bpx_value(bpx_field(j, "Cell", "Electrode area [m2]"), f(Knob::electrode_area), "Cell.Electrode area [m2]");
    scale_bpx_value(bpx_field(j, "Positive electrode", "Maximum concentration [mol.m-3]"), f(Knob::positive_capacity),
                     "Positive electrode.Maximum concentration [mol.m-3]");
    scale_bpx_value(bpx_field(j, "Negative electrode", "Diffusivity [m2.s-1]"), f(Knob::diffusivity_negative),
                     "Negative electrode.Diffusivity [m2.s-1]");
    scale_bpx_value(bpx_field(j, "Positive electrode", "Diffusivity [m2.s-1]"), f(Knob::diffusivity_positive),
                     "Positive electrode.Diffusivity [m2.s-1]");
    scale_bpx_value(bpx_field(j, "Negative electrode", "Reaction rate constant [mol.m-2.s-1]"), f(Knob::rate_negative),
                     "Negative electrode.Reaction rate constant");
    scale_bpx_value(bpx_field(j, "Positive electrode", "Reaction rate constant [mol.m-2.s-1]"), f(Knob::rate_positive),
                     "Positive electrode.Reaction rate constant");
    scale_bpx_value(bpx_field(j, "Electrolyte", "Conductivity [S.m-1]"), f(Knob::conductivity),
                     "Electrolyte.Conductivity [S.m-1]");
    if (has_film())
      bpx_field(j, "User-defined", "Initial SEI resistance [Ohm.m2]") =
          base_.side.initial_film_resistance_ohm_m2 * f(Knob::series_film);
    const double qn = qn0_ * f(Knob::electrode_area);
    const double qp = qp0_ * f(Knob::electrode_area) * f(Knob::positive_capacity);
    // The open-circuit correction (none written while every knot is zero: the template's OCP as it was).
    std::vector<double> knots;
    bool any = false;
    for (std::size_t i = 0; i < knot_y_.size(); ++i) {
      knots.push_back(z[kFirstKnot + static_cast<int>(i)]);
      any = any || knots.back() != 0.0;
    }
    std::unique_ptr<TableFunction> correction;
    if (any) {
      correction = std::make_unique<TableFunction>(knot_y_, knots, "the open-circuit correction");
      add_ocp_correction(bpx_field(j, "Positive electrode", "OCP [V]"), *correction);
    }
    b = balance(base_, qn, qp, z[static_cast<int>(Knob::negative_stoich_full)], s_.v_min, s_.v_max,
                correction.get());
    if (!b.ok) return j;
    bpx_field(j, "Negative electrode", "Minimum stoichiometry") = b.x0;
    bpx_field(j, "Negative electrode", "Maximum stoichiometry") = b.x100;
    bpx_field(j, "Positive electrode", "Minimum stoichiometry") = b.y100;
    bpx_field(j, "Positive electrode", "Maximum stoichiometry") = b.y0;
    bpx_field(j, "Cell", "Nominal cell capacity [A.h]") = b.capacity_ah;
    bpx_field(j, "Cell", "Lower voltage cut-off [V]") = s_.v_min;
    bpx_field(j, "Cell", "Upper voltage cut-off [V]") = s_.v_max;
    return j;
  }

  // Model voltage per piece (NaN on rows whose role is not wanted or the model did not reach);
  // false when the candidate has no electrode balance or the solver fails.
  bool run(const ZVec& z, const DfnMesh& mesh, char want_mask, std::vector<std::vector<double>>& v,
           std::vector<std::string>* early = nullptr) const {
    Balance b;
    const nlohmann::json j = bpx(z, b);
    if (!b.ok) return false;
    CellParameters cell;
    try {
      cell = read_bpx_text(j.dump(), "fitted cell");
    } catch (const InputError&) {
      return false;
    }
    ModelSetup setup{cell, mesh, s_.rtol, 0.0};
    v.assign(pieces_.size(), {});
    for (std::size_t p = 0; p < pieces_.size(); ++p) {
      const FitPiece& piece = pieces_[p];
      std::size_t last = 0;
      bool any = false;
      for (std::size_t k = 0; k < piece.role.size(); ++k)
        if (piece.role[k] & want_mask) last = k, any = true;
      v[p].assign(piece.role.size(), std::numeric_limits<double>::quiet_NaN());
      if (!any) continue;
      Record r = piece.record;
      const std::size_t n = last + 1;
      r.t_s.resize(n), r.current_a.resize(n), r.voltage_v.resize(n), r.mode.resize(n);
      if (!r.temperature_k.empty()) r.temperature_k.resize(n);
      r.initial_depth_ah = std::numeric_limits<double>::quiet_NaN();
      set_initial_state(r, cell, "auto");
      try {
        const ModelRun m = run_model(setup, r, Hypothesis{});
        if (early && m.samples_covered < n)
          early->push_back(fmt::format("the model stopped at row {} of {} in {} ({}): the rest of it is scored with "
                                       "the last residual",
                                       m.samples_covered, n, r.source, m.note));
        const auto res = residual_mv(m.voltage_v, r);  // carries the last reached sample on
        for (std::size_t k = 0; k < n; ++k) v[p][k] = r.voltage_v[k] + 1e-3 * res[k];
      } catch (const RuntimeFailure&) {
        return false;
      }
    }
    return true;
  }

  // Residual (mV) over the wanted rows; empty when the run failed.
  std::vector<double> residual(const ZVec& z, const DfnMesh& mesh, char want) const {
    std::vector<std::vector<double>> v;
    if (!run(z, mesh, want, v)) return {};
    std::vector<double> r;
    for (std::size_t p = 0; p < pieces_.size(); ++p)
      for (std::size_t k = 0; k < v[p].size(); ++k)
        if (pieces_[p].role[k] == want) r.push_back(1e3 * (v[p][k] - pieces_[p].record.voltage_v[k]));
    return r;
  }

 private:
  double number_or_nan(const char* section, const char* key) const {
    const auto& p = tmpl_.at("Parameterisation").at(section);
    if (p.contains(key) && p[key].is_number()) return p[key].get<double>();
    return std::numeric_limits<double>::quiet_NaN();
  }

  nlohmann::json tmpl_;
  std::string name_;
  const std::vector<FitPiece>& pieces_;
  CellFitSettings s_;
  CellParameters base_;
  double qn0_ = 0, qp0_ = 0, x100_0_ = 0;
  std::vector<double> template_values_;
  std::vector<double> knot_y_;  // the correction's knots (positive stoichiometry)
  std::vector<std::string> notes_;
};

double sum_sq(const std::vector<double>& r) {
  double s = 0;
  for (double x : r) s += x * x;
  return r.empty() ? HUGE_VAL : s;
}

ZVec clamp_z(ZVec z, const std::vector<int>& active) {
  for (int k : active) z[k] = std::clamp(z[k], info(static_cast<Knob>(k)).lo, info(static_cast<Knob>(k)).hi);
  return z;
}

struct Search {
  const Problem& problem;
  const CellFitSettings& s;
  const std::function<void(const std::string&)>& log;
  int evaluations = 0;

  std::vector<double> eval(const ZVec& z) {
    ++evaluations;
    return problem.residual(z, s.search_mesh, kRoleTrain);
  }

  // Forward-difference Jacobian (mV per unit z) of the columns `cols`; r0 the residual at z.
  Columns jacobian(const ZVec& z, const std::vector<double>& r0, const std::vector<int>& cols) {
    Columns J(cols.size(), std::vector<double>(r0.size(), 0.0));
    for (std::size_t c = 0; c < cols.size(); ++c) {
      const int k = cols[c];
      ZVec zp = z;
      double h = info(static_cast<Knob>(k)).step;
      if (zp[k] + h > info(static_cast<Knob>(k)).hi) h = -h;
      zp[k] += h;
      std::vector<double> r = eval(zp);
      if (r.size() != r0.size()) {  // a failed run one way: try the other
        h = -h;
        zp[k] = z[k] + h;
        r = eval(zp);
      }
      for (std::size_t i = 0; i < r0.size(); ++i)
        J[c][i] = r.size() == r0.size() ? (r[i] - r0[i]) / h : 0.0;
    }
    return J;
  }

  // Levenberg-Marquardt on the active knobs from z; returns the cost at the end.
  double minimise(ZVec& z, std::vector<double>& r, const std::vector<int>& active, int* iterations) {
    double cost = sum_sq(r), lambda = 1e-2;
    for (int it = 0; it < s.max_iterations && !active.empty(); ++it) {
      const Columns J = jacobian(z, r, active);
      const SmallMatrix H = gram<kKnobs>(J);
      const SmallVector grad = gradient<kKnobs>(J, r);
      bool accepted = false;
      double gain = 0;
      for (int tries = 0; tries < 6 && !accepted; ++tries) {
        SmallMatrix A = H;
        for (long d = 0; d < A.rows(); ++d) A(d, d) += lambda * std::max(H(d, d), 1e-12);
        SmallVector step = A.ldlt().solve(-grad);
        for (std::size_t c = 0; c < active.size(); ++c) {
          const double m = info(static_cast<Knob>(active[c])).max_move;
          step[static_cast<long>(c)] = std::clamp(step[static_cast<long>(c)], -m, m);
        }
        ZVec zn = z;
        for (std::size_t c = 0; c < active.size(); ++c) zn[active[c]] += step[static_cast<long>(c)];
        zn = clamp_z(zn, active);
        std::vector<double> rn = eval(zn);
        const double cn = sum_sq(rn);
        if (cn < cost) {
          gain = (cost - cn) / cost;
          z = zn, r = std::move(rn), cost = cn, accepted = true;
          lambda = std::max(lambda / 3.0, 1e-7);
        } else {
          lambda *= 5.0;
        }
      }
      if (iterations) ++*iterations;
      log(fmt::format("iteration {}: training RMSE {:.3f} mV ({} runs so far)", it + 1,
                      std::sqrt(cost / static_cast<double>(r.size())), evaluations));
      if (!accepted || gain < 1e-4) break;
    }
    return cost;
  }
};

// Largest |cos| between column c and the span of the columns `others` (normalised columns): the
// norm of c's projection on that span, from the small normal equations.
double collinearity(const Columns& Jn, int c, const std::vector<int>& others) {
  if (others.empty()) return 0.0;
  Columns B;
  for (int o : others) B.push_back(Jn[static_cast<std::size_t>(o)]);
  const std::vector<double>& y = Jn[static_cast<std::size_t>(c)];
  SmallVector by(static_cast<Eigen::Index>(B.size()));
  for (std::size_t i = 0; i < B.size(); ++i) by[static_cast<Eigen::Index>(i)] = dot(B[i], y);
  const SmallVector coef = pseudo_inverse(gram<kKnobs>(B)) * by;
  const double projected = by.dot(coef) / std::max(dot(y, y), 1e-300);
  return std::sqrt(std::clamp(projected, 0.0, 1.0));
}

// Candidates: every knob (or those asked for) the template has a value for; `why` says why not.
std::vector<int> candidate_knobs(const Problem& problem, const CellFitSettings& settings, std::vector<std::string>& why) {
  std::vector<int> candidates;
  for (int k = 0; k < kKnobs; ++k) {
    const std::string name = info(static_cast<Knob>(k)).name;
    if (is_knot(k) && k - kFirstKnot >= problem.knot_count()) continue;  // beyond --ocp-knots
    auto asked = [&](const std::string& n) {
      return std::find(settings.only.begin(), settings.only.end(), n) != settings.only.end();
    };
    if (!settings.only.empty() && !asked(name) && !(is_knot(k) && asked("ocp_correction"))) {
      why[static_cast<std::size_t>(k)] = "not asked for (--parameters)";
      continue;
    }
    if (!std::isfinite(problem.template_value(k)) || (k == static_cast<int>(Knob::series_film) && !problem.has_film())) {
      why[static_cast<std::size_t>(k)] = "the template has no numeric value for it";
      continue;
    }
    candidates.push_back(k);
  }
  return candidates;
}

// Identifiability at the template: sensitivity and collinearity of the Jacobian's columns.
std::vector<int> identifiable_knobs(Search& search, const ZVec& z, const std::vector<double>& r,
                                    const std::vector<int>& candidates, const CellFitSettings& settings,
                                    std::vector<std::string>& why) {
  const Columns J0 = search.jacobian(z, r, candidates);
  std::vector<std::pair<double, int>> by_norm;
  for (std::size_t c = 0; c < candidates.size(); ++c)
    by_norm.emplace_back(std::sqrt(dot(J0[c], J0[c]) / static_cast<double>(std::max<std::size_t>(r.size(), 1))),
                         static_cast<int>(c));
  // Priority, not sensitivity, orders the collinearity test: the electrode balance, then the
  // series resistance, then diffusion, kinetics and the electrolyte (a kinetic overpotential at
  // one current level looks like a series resistance; the simpler explanation is kept).
  Columns Jn = J0;
  for (auto& col : Jn) {
    const double n = std::max(std::sqrt(dot(col, col)), 1e-300);
    for (double& v : col) v /= n;
  }
  std::vector<int> chosen_cols, active;
  for (const auto& [rms_mv, c] : by_norm) {
    const int k = candidates[static_cast<std::size_t>(c)];
    // Per factor e; x100 per 0.01; an OCP knot per 0.01 V.
    const double scale = info(static_cast<Knob>(k)).log ? 1.0 : 0.01;
    if (rms_mv * scale < settings.min_sensitivity_mv) {
      why[static_cast<std::size_t>(k)] =
          fmt::format("the voltage hardly depends on it here ({:.3g} mV RMS for {})", rms_mv * scale,
                      info(static_cast<Knob>(k)).log ? "a factor e" : is_knot(k) ? "10 mV" : "0.01");
      continue;
    }
    const double col = collinearity(Jn, c, chosen_cols);
    if (col > settings.max_collinearity) {
      why[static_cast<std::size_t>(k)] =
          fmt::format("its Jacobian column is nearly collinear with those of the parameters fitted before it (balance, series resistance, diffusion, kinetics, electrolyte, open-circuit correction in that order) (|cos| {:.4f})", col);
      continue;
    }
    chosen_cols.push_back(c);
    active.push_back(k);
  }

  return active;
}

// Fits the active knobs; the one with the largest relative sd above the bar leaves and the rest
// is refitted, until every sd is under it. Returns the covariance of the active knobs' z.
SmallMatrix fit_and_prune(Search& search, const Problem& problem, const CellFitSettings& settings,
                              const std::function<void(const std::string&)>& log, ZVec& z,
                              std::vector<double>& r, std::vector<int>& active, std::vector<std::string>& why,
                              CellFitResult& out) {
  SmallMatrix cov;
  double s2 = 0;
  for (int round = 0; round < kKnobs; ++round) {
    search.minimise(z, r, active, &out.iterations);
    if (active.empty()) break;
    const Columns J = search.jacobian(z, r, active);
    const double dof = std::max(1.0, static_cast<double>(r.size()) - static_cast<double>(active.size()));
    s2 = sum_sq(r) / dof;
    cov = s2 * pseudo_inverse(gram<kKnobs>(J));
    // The parameter furthest over its bar leaves, and the rest is refitted: the relative sd for
    // the named parameters, the absolute sd (mV) for the additive OCP knots.
    int worst = -1;
    double worst_ratio = 1.0, worst_sd = 0.0;
    for (std::size_t c = 0; c < active.size(); ++c) {
      const int k = active[c];
      const double sd_z = std::sqrt(std::max(0.0, cov(static_cast<long>(c), static_cast<long>(c))));
      const double sd = is_knot(k) ? 1e3 * sd_z : info(static_cast<Knob>(k)).log ? sd_z : sd_z / std::max(z[k], 1e-9);
      const double ratio = sd / (is_knot(k) ? settings.max_ocp_sd_mv : settings.max_relative_sd);
      if (!(ratio <= worst_ratio))
        worst = static_cast<int>(c), worst_ratio = std::isfinite(ratio) ? ratio : HUGE_VAL, worst_sd = sd;
    }
    // A parameter the search pushed to a bound of its range leaves first: its sd there says nothing
    // and the data want it outside the range searched (e.g. a series film traded for the
    // electrolyte's conductivity, which carries the same resistance).
    int at_bound = -1;
    for (std::size_t c = 0; c < active.size() && at_bound < 0; ++c) {
      const KnobInfo& ki = info(static_cast<Knob>(active[c]));
      if (z[active[c]] <= ki.lo + 1e-9 || z[active[c]] >= ki.hi - 1e-9) at_bound = static_cast<int>(c);
    }
    if (at_bound >= 0) worst = at_bound;
    if (worst < 0) break;
    const int k = active[static_cast<std::size_t>(worst)];
    why[static_cast<std::size_t>(k)] =
        at_bound >= 0 ? std::string("at a bound of its search range at the optimum (the data push it beyond it): not "
                                    "identifiable from these data")
        : is_knot(k) ? fmt::format("standard error {:.3g} mV at the optimum (over {:g} mV): not identifiable from these "
                                 "data",
                                 worst_sd, settings.max_ocp_sd_mv)
                   : fmt::format("relative standard error {:.3g} at the optimum (over {:g}): not identifiable from "
                                 "these data",
                                 worst_sd, settings.max_relative_sd);
    log(fmt::format("{} not identifiable ({}); refitting without it", info(static_cast<Knob>(k)).name,
                    at_bound >= 0 ? std::string("at a search bound")
                                  : fmt::format("{} {:.3g}", is_knot(k) ? "sd in mV" : "relative sd", worst_sd)));
    active.erase(active.begin() + worst);
    z[k] = problem.z0()[k];  // the template's value
    r = search.eval(z);
    if (r.empty()) throw RuntimeFailure("the model failed after a parameter was reset to its template value");
  }
  out.residual_sd_mv = std::sqrt(s2);
  return cov;
}

std::vector<FitParameter> parameters_of(const Problem& problem, const ZVec& z,
                                        const std::vector<int>& active, const SmallMatrix& cov,
                                        const std::vector<std::string>& why) {
  std::vector<FitParameter> out;
  for (int k = 0; k < kKnobs; ++k) {
    if (is_knot(k) && k - kFirstKnot >= problem.knot_count()) break;
    FitParameter p;
    const KnobInfo& ki = info(static_cast<Knob>(k));
    p.name = ki.name, p.unit = ki.unit, p.meaning = ki.meaning;
    if (is_knot(k))
      p.meaning = fmt::format("{} (knot at positive stoichiometry {:.4f})", ki.meaning, problem.knot_y(k - kFirstKnot));
    p.template_value = problem.template_value(k);
    p.value = problem.value(k, z[k]);
    const auto it = std::find(active.begin(), active.end(), k);
    if (it != active.end()) {
      const long c = it - active.begin();
      const double sd_z = std::sqrt(std::max(0.0, cov(c, c)));
      p.fitted = true;
      p.sd = ki.log ? p.value * sd_z : sd_z;  // delta method for the log knobs
      if (z[k] <= ki.lo + 1e-9 || z[k] >= ki.hi - 1e-9) p.note = "at the search bound: the sd is not meaningful";
    } else {
      p.value = p.template_value;
      p.note = why[static_cast<std::size_t>(k)];
    }
    out.push_back(p);
  }

  return out;
}

// The fitted cell and the template, as written, scored on the final mesh and the scoring pieces.
void score_final(const Problem& problem, const std::vector<FitPiece>& score_pieces, const CellFitSettings& settings,
                 const std::function<void(const std::string&)>& log, CellFitResult& out) {
  log("scoring on the final mesh");
  out.fitted = score_cell(out.cell, score_pieces, settings.final_mesh, settings.rtol);
  Balance b0;
  const CellParameters template_cell = read_bpx_text(problem.bpx(problem.z0(), b0).dump(), "template");
  out.templ = score_cell(template_cell, score_pieces, settings.final_mesh, settings.rtol);
  out.rmse_train_mv = out.fitted.rmse_train_mv, out.rmse_heldout_mv = out.fitted.rmse_heldout_mv;
  out.max_abs_heldout_mv = out.fitted.max_abs_heldout_mv;
  out.rmse_template_train_mv = out.templ.rmse_train_mv, out.rmse_template_heldout_mv = out.templ.rmse_heldout_mv;
  out.heldout_samples = out.fitted.heldout_samples;
  for (const auto& st : out.fitted.stops)
    out.notes.push_back(fmt::format("fitted cell: the model stopped at row {} of {} of piece {} (cycle {}, t = {:.1f} "
                                    "s): {}; the rows after it are not scored",
                                    st.row + 1, st.rows, st.piece + 1, st.cycle, st.t_s, st.why));
  if (!out.fitted.stops.empty())
    log(fmt::format("warning: the fitted model stopped early in {} piece(s) (summary.json notes, stops)",
                    out.fitted.stops.size()));
}

// One piece's rows up to its last used one, restarted from its first row's rest voltage.
Record piece_record(const FitPiece& piece, const CellParameters& cell, std::size_t n) {
  Record r = piece.record;
  r.t_s.resize(n), r.current_a.resize(n), r.voltage_v.resize(n), r.mode.resize(n);
  if (!r.temperature_k.empty()) r.temperature_k.resize(n);
  r.initial_depth_ah = std::numeric_limits<double>::quiet_NaN();
  set_initial_state(r, cell, "auto");
  return r;
}

struct Moments {
  double ss = 0, sum = 0, max_abs = 0;
  std::size_t n = 0;
  void add(double e) { ss += e * e, sum += e, max_abs = std::max(max_abs, std::abs(e)), ++n; }
  double rms() const { return n ? std::sqrt(ss / static_cast<double>(n)) : std::nan(""); }
};

}  // namespace

CellScore score_cell(const CellParameters& cell, const std::vector<FitPiece>& pieces, const DfnMesh& mesh,
                     double rtol) {
  CellScore out;
  const ModelSetup setup{cell, mesh, rtol, 0.0};
  std::map<int, std::pair<CycleScore, Moments>> cycles;
  Moments train, held;
  out.voltage_v.assign(pieces.size(), {});
  for (std::size_t p = 0; p < pieces.size(); ++p) {
    const FitPiece& piece = pieces[p];
    out.voltage_v[p].assign(piece.role.size(), std::numeric_limits<double>::quiet_NaN());
    std::size_t n = 0;
    for (std::size_t k = 0; k < piece.role.size(); ++k)
      if (piece.role[k]) n = k + 1;
    if (n == 0) {
      out.initial_states.emplace_back("(no scored rows)");
      continue;
    }
    const Record r = piece_record(piece, cell, n);
    out.initial_states.push_back(r.initial_state_note);
    std::size_t covered = 0;
    std::string why;
    try {
      const ModelRun m = run_model(setup, r, Hypothesis{});
      covered = m.samples_covered;
      for (std::size_t k = 0; k < covered; ++k) out.voltage_v[p][k] = m.voltage_v[k];
      why = m.note;
    } catch (const RuntimeFailure& e) {
      why = e.what();
    }
    for (std::size_t k = 0; k < n; ++k)
      if (std::isfinite(out.voltage_v[p][k])) covered = k + 1;
    if (covered < n)
      out.stops.push_back({p, covered, n, piece.cycle[covered], r.t_s[covered], why.empty() ? "the solver stopped" : why});
    for (std::size_t k = 0; k < n; ++k) {
      if (!piece.role[k]) continue;
      auto& [cs, mom] = cycles[piece.cycle[k]];
      cs.cycle = piece.cycle[k], cs.role = piece.role[k];
      ++cs.samples;
      (piece.role[k] == kRoleTrain ? out.train_samples : out.heldout_samples)++;
      if (!std::isfinite(out.voltage_v[p][k])) continue;
      const double e = 1e3 * (out.voltage_v[p][k] - r.voltage_v[k]);
      mom.add(e);
      (piece.role[k] == kRoleTrain ? train : held).add(e);
    }
  }
  for (auto& [c, cm] : cycles) {
    auto& [cs, mom] = cm;
    cs.scored = mom.n;
    if (mom.n) cs.rmse_mv = mom.rms(), cs.mean_mv = mom.sum / static_cast<double>(mom.n), cs.max_abs_mv = mom.max_abs;
    out.cycles.push_back(cs);
  }
  out.train_scored = train.n, out.heldout_scored = held.n;
  out.rmse_train_mv = train.rms(), out.rmse_heldout_mv = held.rms();
  out.max_abs_heldout_mv = held.n ? held.max_abs : std::nan("");
  return out;
}

std::vector<std::string> fit_parameter_names() {
  std::vector<std::string> n;
  for (int k = 0; k < kNamedKnobs; ++k) n.emplace_back(info(static_cast<Knob>(k)).name);
  n.emplace_back("ocp_correction");  // every knot
  for (int k = kFirstKnot; k < kKnobs; ++k) n.emplace_back(info(static_cast<Knob>(k)).name);
  return n;
}

CellFitResult fit_cell(const nlohmann::json& template_bpx, const std::string& template_name,
                       const std::vector<FitPiece>& search_pieces, const std::vector<FitPiece>& score_pieces,
                       const CellFitSettings& settings, const std::function<void(const std::string&)>& log) {
  Problem problem(template_bpx, template_name, search_pieces, settings);
  CellFitResult out;
  out.notes = problem.notes();
  Search search{problem, settings, log};
  ZVec z = problem.start();
  if (settings.measured_capacity_ah > 0)
    log(fmt::format("start: electrode area x {:.4f} (the largest measured discharge, {:.4f} Ah, in the window)",
                    std::exp(z[0]), settings.measured_capacity_ah));
  std::vector<double> r = search.eval(z);
  if (r.empty())
    throw RuntimeFailure("the template's model fails on the training data (solver or electrode balance); try "
                         "another --template or check the record's voltage window");
  out.train_samples = r.size();
  log(fmt::format("start: training RMSE {:.3f} mV over {} samples (search mesh)",
                  std::sqrt(sum_sq(r) / static_cast<double>(r.size())), r.size()));

  std::vector<std::string> why(kKnobs);
  const std::vector<int> candidates = candidate_knobs(problem, settings, why);
  std::vector<int> active = identifiable_knobs(search, z, r, candidates, settings, why);
  log(fmt::format("fitting {} of {} parameters", active.size(), candidates.size()));
  const SmallMatrix cov = fit_and_prune(search, problem, settings, log, z, r, active, why, out);
  out.rmse_objective_mv = std::sqrt(sum_sq(r) / static_cast<double>(std::max<std::size_t>(r.size(), 1)));
  out.evaluations = search.evaluations;
  out.parameters = parameters_of(problem, z, active, cov, why);
  // Final: the fitted cell as written, scored on the final mesh (train and held out).
  Balance b;
  const nlohmann::json fitted = problem.bpx(z, b);
  out.bpx_text = fitted.dump(1) + "\n";
  out.cell = read_bpx_text(out.bpx_text, "fitted cell");
  out.derived = {{"voltage_window_v", {settings.v_min, settings.v_max}},
                 {"negative_stoichiometry_window", {b.x0, b.x100}},
                 {"positive_stoichiometry_window", {b.y100, b.y0}},
                 {"capacity_ah", b.capacity_ah}};
  if (problem.knot_count() > 0) {
    nlohmann::json knots = {{"positive_stoichiometry", nlohmann::json::array()},
                            {"correction_v", nlohmann::json::array()},
                            {"sd_v", nlohmann::json::array()}};
    for (int i = 0; i < problem.knot_count(); ++i) {
      const FitParameter& p = out.parameters[static_cast<std::size_t>(kFirstKnot + i)];
      knots["positive_stoichiometry"].push_back(problem.knot_y(i));
      knots["correction_v"].push_back(p.value);
      knots["sd_v"].push_back(p.fitted ? nlohmann::json(p.sd) : nlohmann::json(nullptr));
    }
    out.derived["ocp_correction"] = knots;
  }
  Balance b0;
  problem.bpx(problem.z0(), b0);
  out.derived["template_capacity_ah_in_this_window"] = b0.capacity_ah;
  score_final(problem, score_pieces, settings, log, out);
  return out;
}

}  // namespace bms::diagnosis
