#include "baselines/augmented_ekf.hpp"

#include <algorithm>
#include <cmath>

#include <fmt/format.h>

#include "io/input_error.hpp"

namespace bms::baselines {

namespace {
constexpr double kStateStep = 1e-5;  // forward-difference step in scaled coordinates
using Traits = fw::PaperCellTraits;
}  // namespace

AugmentedEkf::AugmentedEkf(const EkfConfig& config, const NoiseLevels& noise, const Cell& initial,
                           double r_film_init_ohm_m2)
    : config_(config), noise_(noise), cell_(initial), r_film_(r_film_init_ohm_m2) {
  int k = 0;
  for (int i = 0; i < Cell::kNrN; ++i) scale_(k++) = Traits::kNeg.max_concentration_mol_m3;
  for (int i = 0; i < Cell::kNrP; ++i) scale_(k++) = Traits::kPos.max_concentration_mol_m3;
  for (int i = 0; i < Cell::kNx; ++i) scale_(k++) = Traits::kElectrolyteInitMolM3;
  scale_(kR) = Traits::kInitialFilmOhmM2;
  // P(0): a uniform shift of each region (the form of an initial-condition error), plus 1 %
  // of it independent per entry so that P is not singular.
  p_.setZero();
  const double v = config.p0_conc_rel * config.p0_conc_rel;
  const int starts[4] = {0, Cell::kNrN, Cell::kNrN + Cell::kNrP, kConc};
  for (int r = 0; r < 3; ++r) {
    for (int a = starts[r]; a < starts[r + 1]; ++a) {
      for (int b = starts[r]; b < starts[r + 1]; ++b) p_(a, b) = v;
      p_(a, a) += 0.01 * v;
    }
  }
  p_(kR, kR) = config.p0_r_rel * config.p0_r_rel;
}

double AugmentedEkf::r_sigma_ohm_m2() const { return std::sqrt(std::max(p_(kR, kR), 0.0)) * scale_(kR); }

AugmentedEkf::Vec AugmentedEkf::pack(const Cell::State& s) const {
  Vec x;
  int k = 0;
  for (int i = 0; i < Cell::kNrN; ++i, ++k) x(k) = s.cs_neg_mol_m3[i] / scale_(k);
  for (int i = 0; i < Cell::kNrP; ++i, ++k) x(k) = s.cs_pos_mol_m3[i] / scale_(k);
  for (int i = 0; i < Cell::kNx; ++i, ++k) x(k) = s.ce_mol_m3[i] / scale_(k);
  x(kR) = 0.0;
  return x;
}

void AugmentedEkf::unpack(const Vec& x, Cell::State& s) const {
  int k = 0;
  for (int i = 0; i < Cell::kNrN; ++i, ++k) s.cs_neg_mol_m3[i] = x(k) * scale_(k);
  for (int i = 0; i < Cell::kNrP; ++i, ++k) s.cs_pos_mol_m3[i] = x(k) * scale_(k);
  for (int i = 0; i < Cell::kNx; ++i, ++k) s.ce_mol_m3[i] = x(k) * scale_(k);
}

// The tick's step without a correction and its derivatives, by forward differences on copies
// of the model.
struct AugmentedEkf::Linearisation {
  explicit Linearisation(const Cell& cell) : s0(cell.state()), base(cell) {}
  Cell::State s0;
  Vec x0;
  Cell base;  // the model stepped without a correction
  fw::ModelTickResult<double> r0{};
  Mat f = Mat::Zero();
  Eigen::Matrix<double, 1, kN> h;
  Vec b;
  double dv_du = 0.0;
};

AugmentedEkf::Linearisation AugmentedEkf::linearise(const Track& t, std::size_t i, double u, bool by_voltage) const {
  Linearisation lin(cell_);
  lin.x0 = pack(lin.s0);
  lin.r0 = step(lin.base, t, i, r_film_);
  const Vec x1 = pack(lin.base.state());
  // Linearisation of the step (columns of F, entries of H) by forward differences.
  for (int j = 0; j < kConc; ++j) {
    Vec xp = lin.x0;
    xp(j) += kStateStep;
    Cell::State sp = lin.s0;
    unpack(xp, sp);
    Cell c = cell_;
    c.restore(sp);
    const auto rj = step_with_input(c, t, i, u, r_film_);
    lin.f.col(j) = (pack(c.state()) - x1) / kStateStep;
    lin.h(j) = (rj.voltage_v - lin.r0.voltage_v) / kStateStep;
  }
  {
    Cell c = cell_;
    const double dr = kStateStep * scale_(kR);
    const auto rr = step_with_input(c, t, i, u, r_film_ + dr);
    lin.f.col(kR) = (pack(c.state()) - x1) / kStateStep;
    lin.f(kR, kR) = 1.0;
    lin.h(kR) = (rr.voltage_v - lin.r0.voltage_v) / kStateStep;
  }
  const double du = by_voltage ? kVoltageStepV : kCurrentStepA;
  Cell c = cell_;
  const auto ru = step_with_input(c, t, i, u + du, r_film_);
  lin.b = (pack(c.state()) - x1) / du;
  lin.dv_du = (ru.voltage_v - lin.r0.voltage_v) / du;
  return lin;
}

// The measurement update with out.innovation_v; false (nothing changed) when the corrected
// state is one the model cannot take.
bool AugmentedEkf::correct(const Track& t, std::size_t i, double u, const Linearisation& lin, EkfTick& out) {
  const double innovation = out.innovation_v;
  const double r_var = noise_.sigma_v_v * noise_.sigma_v_v + config_.model_error_v * config_.model_error_v +
                       noise_.sigma_i_a * noise_.sigma_i_a * lin.dv_du * lin.dv_du;
  const Vec ph = p_ * lin.h.transpose();
  const double s = (lin.h * ph)(0) + r_var;
  const Vec k = ph / s;
  Vec xc = lin.x0 + k * innovation;
  Cell::State sc = lin.s0;
  unpack(xc, sc);
  Cell corrected = cell_;
  const double r_corr = r_film_ + k(kR) * innovation * scale_(kR);
  bool ok = corrected.restore(sc);
  fw::ModelTickResult<double> rc{};
  if (ok) {
    rc = step_with_input(corrected, t, i, u, r_corr);
    ok = rc.valid;
  }
  if (!ok) return false;
  const Mat a = Mat::Identity() - k * lin.h;
  p_ = a * p_ * a.transpose() + (k * k.transpose()) * r_var;
  r_film_ = r_corr;
  cell_ = corrected;
  out = {r_film_, r_sigma_ohm_m2(), rc.voltage_v, innovation, true, false};
  return true;
}

EkfTick AugmentedEkf::tick(const Track& t, std::size_t i, bool update) {
  const double u = t.input(i);
  const bool by_voltage = t.voltage_driven[i] != 0;
  update = update && !by_voltage;
  const Linearisation lin = linearise(t, i, u, by_voltage);

  EkfTick out{r_film_, 0.0, lin.r0.voltage_v, 0.0, false, false};
  if (update) {
    const double y = t.data->voltage_v[i];
    const double r_var = noise_.sigma_v_v * noise_.sigma_v_v + config_.model_error_v * config_.model_error_v +
                         noise_.sigma_i_a * noise_.sigma_i_a * lin.dv_du * lin.dv_du;
    const double innovation = y - lin.r0.voltage_v;
    const Vec ph = p_ * lin.h.transpose();
    const double s = (lin.h * ph)(0) + r_var;
    out.innovation_v = innovation;
    if (config_.gate_sigmas > 0.0 && innovation * innovation > config_.gate_sigmas * config_.gate_sigmas * s) {
      update = false;
      out.gated = true;
    }
  }
  // A correction the model cannot take is dropped, not forced.
  if (!update || !correct(t, i, u, lin, out)) cell_ = lin.base;
  if (!out.updated) out.r_sigma_ohm_m2 = r_sigma_ohm_m2();

  const double sigma_u = by_voltage ? noise_.sigma_v_v : noise_.sigma_i_a;
  Mat q = (lin.b * lin.b.transpose()) * (sigma_u * sigma_u);
  const double qc = config_.q_conc_rel_per_sqrt_s * config_.q_conc_rel_per_sqrt_s * t.dt_s;
  for (int j = 0; j < kConc; ++j) q(j, j) += qc;
  const double qr = config_.q_r_ohm_m2_per_sqrt_s / scale_(kR);
  q(kR, kR) += qr * qr * t.dt_s;
  p_ = lin.f * p_ * lin.f.transpose() + q;
  p_ = 0.5 * (p_ + p_.transpose());  // keep it symmetric against round-off drift
  return out;
}

EkfRun run_ekf(const Track& t, const NoiseLevels& noise, const EkfConfig& config, const Cell& initial,
               double r_film_init_ohm_m2) {
  AugmentedEkf ekf(config, noise, initial, r_film_init_ohm_m2);
  EkfRun out;
  out.r_est.resize(t.size());
  out.r_sigma.resize(t.size());
  out.model_voltage_v.resize(t.size());
  for (std::size_t i = 0; i < t.size(); ++i) {
    const fw::Mode m = t.mode[i];
    const bool learn = m == fw::Mode::cc_charge || (config.update_all_cc && m == fw::Mode::cc_discharge);
    const EkfTick k = ekf.tick(t, i, learn);
    out.r_est[i] = k.r_film_ohm_m2;
    out.r_sigma[i] = k.r_sigma_ohm_m2;
    out.model_voltage_v[i] = k.voltage_v;
    if (k.updated) ++out.updates;
    if (k.gated) ++out.gated;
  }
  return out;
}

}  // namespace bms::baselines
