#include "dfn/dfn_model.hpp"

#include <algorithm>
#include <stdexcept>

namespace bms {
namespace {

using fw::Dual;

// Keeps trial states that the Newton iteration may visit away from the singular edges of the
// kinetics (sqrt of a negative concentration, 1/x in the OCP fits).
template <typename T>
T clamp_above(const T& x, double lo) {
  return fw::value_of(x) < lo ? T(lo) : x;
}
template <typename T>
T clamp_between(const T& x, double lo, double hi) {
  if (fw::value_of(x) < lo) return T(lo);
  if (fw::value_of(x) > hi) return T(hi);
  return x;
}

template <typename T>
T apply(const ScalarFunction& f, const T& x) {
  if constexpr (std::is_same_v<T, double>) {
    return f.value(x);
  } else {
    double v = 0.0, d = 0.0;
    f.value_and_derivative(x.v, v, d);
    return T{v, d * x.d};
  }
}

using std::exp;
using std::log;
using std::sinh;
using std::sqrt;
using fw::exp;
using fw::log;
using fw::sinh;
using fw::sqrt;

}  // namespace

DfnModel::DfnModel(const CellParameters& cell, const DfnMesh& mesh, double temperature_k)
    : cell_(cell), mesh_(mesh), temperature_k_(temperature_k) {
  if (mesh.n_neg < 2 || mesh.n_sep < 1 || mesh.n_pos < 2 || mesh.n_r < 3)
    throw std::invalid_argument("DfnMesh: need at least 2 cells per electrode, 1 in the separator, 3 radial");
  f_rt_ = kFaraday_c_mol / (kGas_j_mol_k * temperature_k_);
  nx_ = mesh.n_neg + mesh.n_sep + mesh.n_pos;
  ne_ = mesh.n_neg + mesh.n_pos;
  cs_end_ = 2 * nx_ + ne_ * mesh.n_r;
  n_ = cs_end_ + 2 * ne_ + 3;

  dx_.resize(nx_);
  eps_.resize(nx_);
  te_.resize(nx_);
  a_.resize(nx_);
  for (int k = 0; k < nx_; ++k) {
    if (k < mesh.n_neg) {
      dx_[k] = cell.negative.thickness_m / mesh.n_neg;
      eps_[k] = cell.negative.porosity;
      te_[k] = cell.negative.transport_efficiency;
      a_[k] = cell.negative.surface_area_per_volume_m();
    } else if (k < mesh.n_neg + mesh.n_sep) {
      dx_[k] = cell.separator.thickness_m / mesh.n_sep;
      eps_[k] = cell.separator.porosity;
      te_[k] = cell.separator.transport_efficiency;
      a_[k] = 0.0;
    } else {
      dx_[k] = cell.positive.thickness_m / mesh.n_pos;
      eps_[k] = cell.positive.porosity;
      te_[k] = cell.positive.transport_efficiency;
      a_[k] = cell.positive.surface_area_per_volume_m();
    }
  }
  const int nr = mesh.n_r;
  shell_vol_.resize(2 * nr);
  face_r2_.resize(2 * (nr + 1));
  // Shells are finer towards the surface, where the concentration gradient is steepest:
  // face i sits at R f(i/n) with f(s) = s + b s (1 - s), so the surface shell is (1 - b)
  // times and the centre shell (1 + b) times the uniform width.
  constexpr double kSurfaceRefinement = 0.6;
  center_dist_.resize(2 * (nr - 1));
  surface_half_.resize(2);
  for (int side = 0; side < 2; ++side) {
    const double radius = side == 0 ? cell.negative.particle_radius_m : cell.positive.particle_radius_m;
    std::vector<double> face(nr + 1);
    for (int i = 0; i <= nr; ++i) {
      const double u = static_cast<double>(i) / nr;
      face[i] = radius * (u + kSurfaceRefinement * u * (1.0 - u));
      face_r2_[side * (nr + 1) + i] = face[i] * face[i];
    }
    for (int i = 0; i < nr; ++i)
      shell_vol_[side * nr + i] = (face[i + 1] * face[i + 1] * face[i + 1] - face[i] * face[i] * face[i]) / 3.0;
    for (int i = 0; i + 1 < nr; ++i)
      center_dist_[side * (nr - 1) + i] = 0.5 * (face[i + 2] - face[i]);
    surface_half_[side] = 0.5 * (face[nr] - face[nr - 1]);
  }

  mass_.assign(n_, 0.0);
  atol_scale_.assign(n_, 1.0);
  for (int k = 0; k < nx_; ++k) {
    mass_[idx_ce(k)] = eps_[k] * dx_[k];
    atol_scale_[idx_ce(k)] = cell.initial_electrolyte_mol_m3;
  }
  for (int e = 0; e < ne_; ++e) {
    const int side = e < mesh.n_neg ? 0 : 1;
    const double cmax = side == 0 ? cell.negative.max_concentration_mol_m3 : cell.positive.max_concentration_mol_m3;
    for (int r = 0; r < nr; ++r) {
      mass_[idx_cs(e, r)] = shell_vol_[side * nr + r];
      atol_scale_[idx_cs(e, r)] = cmax;
    }
  }
  mass_[idx_film()] = 1.0;
  atol_scale_[idx_film()] = std::max(cell.side.initial_film_resistance_ohm_m2, 1e-3);
  mass_[idx_charge()] = 1.0;
  atol_scale_[idx_charge()] = std::max(cell.nominal_capacity_ah, 1.0);
}

std::vector<double> DfnModel::initial_state(double stoich_neg, double stoich_pos, double ce,
                                            double r_film) const {
  std::vector<double> y(n_, 0.0);
  const double un = cell_.negative.ocp_v->value(stoich_neg);
  const double up = cell_.positive.ocp_v->value(stoich_pos);
  for (int k = 0; k < nx_; ++k) {
    y[idx_ce(k)] = ce;
    y[idx_phie(k)] = -un;
  }
  for (int e = 0; e < ne_; ++e) {
    const bool neg = e < mesh_.n_neg;
    const double c = neg ? stoich_neg * cell_.negative.max_concentration_mol_m3
                         : stoich_pos * cell_.positive.max_concentration_mol_m3;
    for (int r = 0; r < mesh_.n_r; ++r) y[idx_cs(e, r)] = c;
    y[idx_phis(e)] = neg ? 0.0 : up - un;
    y[idx_j(e)] = 0.0;
  }
  y[idx_current()] = 0.0;
  y[idx_film()] = r_film;
  y[idx_charge()] = 0.0;
  return y;
}

double DfnModel::current_setpoint_a(double t) const {
  if (control_.kind == ControlKind::profile) {
    const auto& ts = *control_.profile_t_s;
    const auto& is = *control_.profile_current_a;
    if (t <= ts.front()) return is.front();
    if (t >= ts.back()) return is.back();
    const auto it = std::upper_bound(ts.begin(), ts.end(), t);
    const size_t i = static_cast<size_t>(it - ts.begin());
    const double w = (t - ts[i - 1]) / (ts[i] - ts[i - 1]);
    return is[i - 1] + w * (is[i] - is[i - 1]);
  }
  return control_.value;
}

double DfnModel::film_growth_factor() const {
  const auto& s = cell_.side;
  return s.molar_mass_kg_mol / (s.density_kg_m3 * kFaraday_c_mol * s.film_conductivity_s_m);
}

template <typename T>
T DfnModel::side_current(const T& phis, const T& phie, const T& j, const T& r) const {
  const auto& s = cell_.side;
  const T eta_s = phis - phie - s.reference_potential_v - j * r;
  return -s.exchange_current_a_m2 * exp(clamp_between(T(-s.transfer_coefficient * f_rt_) * eta_s, -60.0, 60.0));
}

template <typename T>
void DfnModel::eval_g(double t, const T* y, T* g) const {
  const int nn = mesh_.n_neg, ns = mesh_.n_sep, nr = mesh_.n_r;
  const double area = cell_.electrode_area_m2;
  const double tplus = cell_.electrolyte.transference_number;
  const double nu = 2.0 * (1.0 - tplus) / f_rt_;  // diffusion-potential coefficient (V), TDF = 1
  const T current = y[idx_current()];
  const T i_app = current / area;  // A/m2, positive = discharge
  const T r_film = y[idx_film()];
  const bool side_on = cell_.side.enabled;

  // Electrolyte: concentration flux and ionic current on the internal faces.
  T flux_left = T(0.0), ie_left = T(0.0);
  T ce_k = clamp_above(y[idx_ce(0)], 1e-3);
  T d_k = apply(*cell_.electrolyte.diffusivity_m2_s, ce_k) * te_[0];
  T kap_k = apply(*cell_.electrolyte.conductivity_s_m, ce_k) * te_[0];
  T psi_k = y[idx_phie(0)] - nu * log(ce_k);
  for (int k = 0; k < nx_; ++k) {
    T flux_right = T(0.0), ie_right = T(0.0);
    T ce_n{}, d_n{}, kap_n{}, psi_n{};
    if (k + 1 < nx_) {
      ce_n = clamp_above(y[idx_ce(k + 1)], 1e-3);
      d_n = apply(*cell_.electrolyte.diffusivity_m2_s, ce_n) * te_[k + 1];
      kap_n = apply(*cell_.electrolyte.conductivity_s_m, ce_n) * te_[k + 1];
      psi_n = y[idx_phie(k + 1)] - nu * log(ce_n);
      // Series resistance of the two half cells: exact at region interfaces.
      const T rd = dx_[k] / (2.0 * d_k) + dx_[k + 1] / (2.0 * d_n);
      const T rk = dx_[k] / (2.0 * kap_k) + dx_[k + 1] / (2.0 * kap_n);
      flux_right = (y[idx_ce(k + 1)] - y[idx_ce(k)]) / rd;
      ie_right = -(psi_n - psi_k) / rk;
    }
    T source = T(0.0);  // volumetric reaction current J (A/m3) times dx
    if (a_[k] > 0.0) {
      const int e = k < nn ? k : k - ns;
      source = a_[k] * y[idx_j(e)] * dx_[k];
    }
    g[idx_ce(k)] = flux_right - flux_left + (1.0 - tplus) / kFaraday_c_mol * source;
    g[idx_phie(k)] = ie_right - ie_left - source;
    flux_left = flux_right;
    ie_left = ie_right;
    if (k + 1 < nx_) {
      ce_k = ce_n; d_k = d_n; kap_k = kap_n; psi_k = psi_n;
    }
  }

  // Electrodes: solid potential, kinetics, particles.
  T js_weighted_sum = T(0.0);
  for (int e = 0; e < ne_; ++e) {
    const bool neg = e < nn;
    const int k = neg ? e : e + ns;
    const ElectrodeParameters& p = neg ? cell_.negative : cell_.positive;
    const int first = neg ? 0 : nn, last = neg ? nn - 1 : ne_ - 1;
    const double sigma = p.conductivity_eff_s_m;
    const double h = dx_[k];
    // Solid current on the faces (positive in +x): I/A at the current collectors, 0 at the separator.
    const T is_left = e == first ? (neg ? i_app : T(0.0)) : -sigma * (y[idx_phis(e)] - y[idx_phis(e - 1)]) / h;
    const T is_right = e == last ? (neg ? T(0.0) : i_app) : -sigma * (y[idx_phis(e + 1)] - y[idx_phis(e)]) / h;
    const T j = y[idx_j(e)];
    g[idx_phis(e)] = is_right - is_left + a_[k] * j * h;

    // Particle: finite volumes in r; molar flux out of the surface from the intercalation part.
    const int side = neg ? 0 : 1;
    const double ds = p.solid_diffusivity_m2_s;
    const T phis = y[idx_phis(e)], phie = y[idx_phie(k)];
    T js = T(0.0);
    if (neg && side_on) js = side_current(phis, phie, j, r_film);
    const T flux_out = (j - js) / kFaraday_c_mol;
    for (int r = 0; r < nr; ++r) {
      const T c = y[idx_cs(e, r)];
      const T in_right = r + 1 < nr ? face_r2_[side * (nr + 1) + r + 1] * ds * (y[idx_cs(e, r + 1)] - c) /
                                          center_dist_[side * (nr - 1) + r]
                                    : -face_r2_[side * (nr + 1) + nr] * flux_out;
      const T in_left = r > 0 ? face_r2_[side * (nr + 1) + r] * ds * (c - y[idx_cs(e, r - 1)]) /
                                    center_dist_[side * (nr - 1) + r - 1]
                              : T(0.0);
      g[idx_cs(e, r)] = in_right - in_left;
    }
    const double cmax = p.max_concentration_mol_m3;
    const T c_surf = clamp_between(y[idx_cs(e, nr - 1)] - surface_half_[side] * flux_out / ds, 1e-6 * cmax, (1.0 - 1e-6) * cmax);
    const T ce = clamp_above(y[idx_ce(k)], 1e-3);
    const T i0 = p.i0_coefficient * sqrt(ce * c_surf * (cmax - c_surf));
    const T ocp = apply(*p.ocp_v, c_surf / cmax);
    T eta = phis - phie - ocp;
    if (neg) eta = eta - j * r_film;
    // Saturating the exponent keeps wild Newton trial states (consistent initialisation after
    // a large current step) finite; converged states are far inside the limit.
    g[idx_j(e)] = j - (2.0 * i0 * sinh(clamp_between(T(0.5 * f_rt_) * eta, -60.0, 60.0)) + js);
    if (neg) js_weighted_sum = js_weighted_sum + js * h;
  }

  // Ground: the negative current collector is at 0 V (replaces one redundant charge balance).
  const double h_n = dx_[0], h_p = dx_[nx_ - 1];
  g[idx_phie(0)] = y[idx_phis(0)] + i_app * (0.5 * h_n / cell_.negative.conductivity_eff_s_m);

  const T v_terminal = y[idx_phis(ne_ - 1)] - i_app * (0.5 * h_p / cell_.positive.conductivity_eff_s_m) -
                       y[idx_phis(0)] - i_app * (0.5 * h_n / cell_.negative.conductivity_eff_s_m) -
                       effects_.contact_resistance_ohm * current;
  switch (control_.kind) {
    case ControlKind::current:
    case ControlKind::profile:
      g[idx_current()] = current - current_setpoint_a(t);
      break;
    case ControlKind::voltage:
      g[idx_current()] = v_terminal - control_.value;
      break;
  }
  const T mean_js = js_weighted_sum / cell_.negative.thickness_m;
  g[idx_film()] = film_frozen_ || !side_on ? T(0.0) : -film_growth_factor() * mean_js;
  g[idx_charge()] = current / 3600.0;
}

double DfnModel::terminal_voltage_v(const double* y) const {
  const double i_app = y[idx_current()] / cell_.electrode_area_m2;
  return y[idx_phis(ne_ - 1)] - i_app * (0.5 * dx_[nx_ - 1] / cell_.positive.conductivity_eff_s_m) -
         y[idx_phis(0)] - i_app * (0.5 * dx_[0] / cell_.negative.conductivity_eff_s_m) -
         effects_.contact_resistance_ohm * y[idx_current()];
}

double DfnModel::mean_side_current_a_m2(const double* y) const {
  if (!cell_.side.enabled) return 0.0;
  double sum = 0.0;
  for (int e = 0; e < mesh_.n_neg; ++e)
    sum += side_current(y[idx_phis(e)], y[idx_phie(e)], y[idx_j(e)], y[idx_film()]) * dx_[e];
  return sum / cell_.negative.thickness_m;
}

void DfnModel::film_row_jacobian(const double* y, std::vector<std::pair<int, double>>& out) const {
  out.clear();
  const double r = y[idx_film()];
  const double alpha_f = cell_.side.transfer_coefficient * f_rt_;
  const double scale = film_frozen_ || !cell_.side.enabled ? 0.0 : -film_growth_factor() / cell_.negative.thickness_m;
  double d_r = 0.0;
  for (int e = 0; e < mesh_.n_neg; ++e) {
    const double j = y[idx_j(e)];
    const double js = side_current(y[idx_phis(e)], y[idx_phie(e)], j, r);
    const double arg = -alpha_f * (y[idx_phis(e)] - y[idx_phie(e)] - cell_.side.reference_potential_v - j * r);
    const bool saturated = arg <= -60.0 || arg >= 60.0;  // as in side_current()
    const double w = saturated ? 0.0 : scale * dx_[e] * (-alpha_f) * js;  // d js / d eta_s = -alpha f js
    out.emplace_back(idx_phis(e), w);
    out.emplace_back(idx_phie(e), -w);
    out.emplace_back(idx_j(e), -w * r);
    d_r += -w * j;
  }
  out.emplace_back(idx_film(), d_r);
}

double DfnModel::lithium_inventory_mol(const double* y) const {
  const int nn = mesh_.n_neg, ns = mesh_.n_sep, nr = mesh_.n_r;
  double total = 0.0;
  for (int k = 0; k < nx_; ++k) total += eps_[k] * y[idx_ce(k)] * dx_[k];
  for (int e = 0; e < ne_; ++e) {
    const bool neg = e < nn;
    const int k = neg ? e : e + ns, side = neg ? 0 : 1;
    const ElectrodeParameters& p = neg ? cell_.negative : cell_.positive;
    const double radius = p.particle_radius_m;
    double moles_per_particle_scaled = 0.0;
    for (int r = 0; r < nr; ++r) moles_per_particle_scaled += y[idx_cs(e, r)] * shell_vol_[side * nr + r];
    total += p.solid_fraction * dx_[k] * moles_per_particle_scaled * 3.0 / (radius * radius * radius);
  }
  return total * cell_.electrode_area_m2;
}

double DfnModel::mean_stoich(const double* y, bool negative) const {
  const int nr = mesh_.n_r;
  const int first = negative ? 0 : mesh_.n_neg, count = negative ? mesh_.n_neg : mesh_.n_pos;
  const ElectrodeParameters& p = negative ? cell_.negative : cell_.positive;
  const int side = negative ? 0 : 1;
  const double r3 = p.particle_radius_m * p.particle_radius_m * p.particle_radius_m;
  double sum = 0.0;
  for (int e = first; e < first + count; ++e)
    for (int r = 0; r < nr; ++r) sum += y[idx_cs(e, r)] * shell_vol_[side * nr + r] * 3.0 / r3;
  return sum / count / p.max_concentration_mol_m3;
}

double DfnModel::surface_stoich(const double* y, int e) const {
  const bool neg = e < mesh_.n_neg;
  const ElectrodeParameters& p = neg ? cell_.negative : cell_.positive;
  return y[idx_cs(e, mesh_.n_r - 1)] / p.max_concentration_mol_m3;
}

double DfnModel::lithium_loss_mol(double r_film, double r_film_start) const {
  if (!cell_.side.enabled) return 0.0;
  // dR/dt = -factor mean(js); Li loss rate = -A L_n a_n mean(js) / F.
  const double per_r = cell_.electrode_area_m2 * cell_.negative.thickness_m *
                       cell_.negative.surface_area_per_volume_m() / (kFaraday_c_mol * film_growth_factor());
  return (r_film - r_film_start) * per_r;
}

template void DfnModel::eval_g<double>(double, const double*, double*) const;
template void DfnModel::eval_g<fw::Dual<double>>(double, const fw::Dual<double>*, fw::Dual<double>*) const;

}  // namespace bms
