#include "dfn/dfn_model.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

#include "cell/diffusivity_profile.hpp"
#include "dfn/multi_dual.hpp"
#include "dfn/sparsity_tracer.hpp"
#include "io/input_error.hpp"

namespace bms {
namespace {

using fw::Dual;

// Keeps trial states that the Newton iteration may visit away from the singular edges of the
// kinetics (sqrt of a negative concentration, 1/x in the OCP fits).
// The sparsity tracer keeps its argument's dependences whatever the value (structural pattern).
template <typename T>
T clamp_above(const T& x, double lo) {
  if constexpr (std::is_same_v<T, SparsityTracer>) return x.with_value(std::max(x.v, lo));
  return fw::value_of(x) < lo ? T(lo) : x;
}
template <typename T>
T clamp_between(const T& x, double lo, double hi) {
  if constexpr (std::is_same_v<T, SparsityTracer>) return x.with_value(std::min(std::max(x.v, lo), hi));
  if (fw::value_of(x) < lo) return T(lo);
  if (fw::value_of(x) > hi) return T(hi);
  return x;
}

template <typename T>
T apply(const ScalarFunction& f, const T& x) {
  if constexpr (std::is_same_v<T, double>) {
    return f.value(x);
  } else if constexpr (std::is_same_v<T, SparsityTracer>) {
    return x.with_value(f.value(x.v));
  } else if constexpr (std::is_same_v<T, JacobianDual>) {
    double v = 0.0, d = 0.0;
    f.value_and_derivative(x.v, v, d);
    return T::chain(x, v, d);
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

// Physical ranges of the effects and of the cell fields they need; InputError naming the effect.
void check_effects(const CellParameters& cell, const ModelEffects& effects, double temperature_k) {
  const auto bad = [](const std::string& what) { throw InputError("effect " + what); };
  // Physical ranges, generous: a cell's contact resistance is milliohms (1 ohm drops 2.5 V at
  // 2.5 A); an 18650's loss to ambient is 0.01-1 W/K, and 1e5 W/K holds a cell at ambient.
  if (!(effects.contact_resistance_ohm >= 0.0 && effects.contact_resistance_ohm <= 1.0))
    bad("contact_resistance: must be in [0, 1] ohm (a cell's is milliohms)");
  if (!(std::isfinite(effects.hysteresis_v) && effects.hysteresis_v >= 0.0 && effects.hysteresis_v <= 0.5))
    bad("hysteresis: must be in [0, 0.5] V (half the gap between the branches)");
  if (!(std::isfinite(effects.hysteresis_rate_per_soc) && effects.hysteresis_rate_per_soc > 0.0))
    bad("hysteresis rate: must be > 0 per unit of state of charge");
  if (!(std::abs(effects.hysteresis_initial_branch) <= 1.0)) bad("hysteresis initial branch: must be in [-1, 1]");
  // Up to 1e6 W/K: tests clamp the cell at ambient with a huge coefficient; the command line
  // caps a real cell's at 1000 W/K.
  if (!(effects.thermal_h_w_per_k >= 0.0 && effects.thermal_h_w_per_k <= 1e6))
    bad("thermal: heat-transfer coefficient must be in [0, 1e6] W/K");
  for (const double sigma : {effects.particle_size_sigma, effects.particle_size_negative_sigma})
    if (!(std::isfinite(sigma) && sigma >= 0.0 && sigma <= 1.5))
      bad("particle_size: log-space standard deviation of the particle radius must be in [0, 1.5]");
  // The film row and its Jacobian follow the plain anode particle only.
  if (effects.particle_size_negative_sigma > 0.0 && cell.side.enabled)
    bad("particle_size_negative: not available together with the side reaction");
  if (effects.particle_size_populations != 3 && effects.particle_size_populations != 5)
    bad("particle_size populations: must be 3 or 5");
  // Four decades slower to two faster at full lithiation; a knee inside the stoichiometry range.
  if (!(effects.diffusivity_profile_positive >= -4.0 && effects.diffusivity_profile_positive <= 2.0))
    bad("diffusivity_profile_positive: log10 of the factor at full lithiation must be in [-4, 2]");
  if (!(effects.diffusivity_profile_positive_knee >= 0.0 && effects.diffusivity_profile_positive_knee <= 0.99))
    bad("diffusivity_profile_positive_knee: the knee stoichiometry must be in [0, 0.99]");
  // Up to 100 ohm m2 of particle surface (40 ohm at the cell level on an 18650's 25 m2 of cathode
  // surface: past any cell that still discharges); up to six decades of rise to x = 1.
  if (!(effects.resistive_reactant_positive_ohm_m2 >= 0.0 && effects.resistive_reactant_positive_ohm_m2 <= 100.0))
    bad("resistive_reactant_positive: the resistance below the knee must be in [0, 100] ohm m2");
  if (!(effects.resistive_reactant_positive_log10 >= 0.0 && effects.resistive_reactant_positive_log10 <= 6.0))
    bad("resistive_reactant_positive_log10: decades of rise to full lithiation must be in [0, 6]");
  if (!(effects.resistive_reactant_positive_knee >= 0.0 && effects.resistive_reactant_positive_knee <= 0.99))
    bad("resistive_reactant_positive_knee: the knee stoichiometry must be in [0, 0.99]");
  // Measured activation energies of LiFePO4's electronic conduction are 0.1-0.4 eV (10-40 kJ/mol,
  // docs/results/diagnosis.md); 200 kJ/mol leaves room without letting a few kelvin switch it off.
  if (!(effects.resistive_reactant_positive_ea_j_mol >= 0.0 && effects.resistive_reactant_positive_ea_j_mol <= 2e5))
    bad("resistive_reactant_positive_ea: the activation energy must be in [0, 200000] J/mol");
  // The lithium loss is read back from the film through the growth factor: it must not be 0.
  if (!(std::isfinite(cell.side.film_growth_scale) && cell.side.film_growth_scale > 0.0))
    throw InputError("film_growth_scale: must be a finite value > 0");
  if (!(temperature_k > 150.0 && temperature_k < 500.0))
    bad("temperature " + std::to_string(temperature_k) + " K: outside 150-500 K");
  if (effects.hysteresis_on() && !(cell.nominal_capacity_ah > 0.0))
    bad("hysteresis: cell '" + cell.name + "' has no nominal capacity to scale the rate");
}

}  // namespace

ModelEffects with_cell_effects(const CellParameters& cell, ModelEffects effects) {
  const CellEffectParameters& c = cell.effects;
  effects.contact_resistance_ohm += c.contact_resistance_ohm;
  if (effects.hysteresis_v == 0.0) effects.hysteresis_v = c.hysteresis_v;
  if (c.hysteresis_rate_per_soc > 0.0) effects.hysteresis_rate_per_soc = c.hysteresis_rate_per_soc;
  if (effects.thermal_h_w_per_k == 0.0) effects.thermal_h_w_per_k = c.thermal_h_w_per_k;
  if (effects.particle_size_sigma == 0.0) effects.particle_size_sigma = c.particle_size_sigma;
  if (effects.diffusivity_profile_positive == 0.0) {
    effects.diffusivity_profile_positive = c.diffusivity_profile_positive;
    effects.diffusivity_profile_positive_knee = c.diffusivity_profile_positive_knee;
  }
  if (effects.resistive_reactant_positive_ohm_m2 == 0.0) {
    effects.resistive_reactant_positive_ohm_m2 = c.resistive_reactant_positive_ohm_m2;
    effects.resistive_reactant_positive_log10 = c.resistive_reactant_positive_log10;
    effects.resistive_reactant_positive_knee = c.resistive_reactant_positive_knee;
  }
  return effects;
}

DfnModel::DfnModel(const CellParameters& cell, const DfnMesh& mesh, double temperature_k,
                   const ModelEffects& effects)
    : cell_(cell), mesh_(mesh), temperature_k_(temperature_k), effects_(with_cell_effects(cell, effects)) {
  if (mesh.n_neg < 2 || mesh.n_sep < 1 || mesh.n_pos < 2 || mesh.n_r < 3)
    throw std::invalid_argument("DfnMesh: need at least 2 cells per electrode, 1 in the separator, 3 radial");
  check_effects(cell, effects_, temperature_k);
  cell_.positive.solid_diffusivity_factor =
      with_knee_profile(cell_.positive.solid_diffusivity_factor, effects_.diffusivity_profile_positive,
                        effects_.diffusivity_profile_positive_knee);
  if (effects_.resistive_reactant_on())
    reactant_factor_ = std::make_shared<KneeDiffusivityProfile>(effects_.resistive_reactant_positive_log10,
                                                                effects_.resistive_reactant_positive_knee);
  if (effects_.thermal_on()) {
    const auto& th = cell.thermal;
    heat_capacity_j_k_ = th.specific_heat_j_kg_k * th.density_kg_m3 * th.volume_m3;
    if (!(heat_capacity_j_k_ > 0.0))
      throw InputError("effect thermal: cell '" + cell.name +
                       "' has no heat capacity (BPX Cell: 'Specific heat capacity [J.K-1.kg-1]', "
                       "'Density [kg.m-3]', 'Volume [m3]')");
  }
  temperature_dependent_ = effects_.thermal_on() || temperature_k != cell.thermal.reference_temperature_k;
  f_rt_ = kFaradayC_mol / (kGas_j_mol_k * temperature_k_);
  nx_ = mesh.n_neg + mesh.n_sep + mesh.n_pos;
  ne_ = mesh.n_neg + mesh.n_pos;
  cs_end_ = 2 * nx_ + ne_ * mesh.n_r;
  n_ = cs_end_ + 2 * ne_ + 3;
  // Effect states go after the plain model's, so its layout does not depend on them.
  if (effects_.hysteresis_on()) idx_hyst_ = n_++;
  if (effects_.thermal_on()) {
    idx_heat0_ = n_;
    n_ += nx_;
    idx_temp_ = n_++;
  }
  layout_populations();
  layout_regions();
  layout_shells();
  set_masses_and_scales();
}

// Particle-size populations: Gauss-Hermite radius scales and weights, and their extra states.
void DfnModel::layout_populations() {
  nodes_[0] = mesh_.n_neg;
  nodes_[1] = mesh_.n_pos;
  for (int side = 0; side < 2; ++side) {
    pop_scale_[side] = {1.0};
    pop_weight_[side] = {1.0};
    const double sigma = side == 0 ? effects_.particle_size_negative_sigma : effects_.particle_size_sigma;
    if (!(sigma > 0.0)) continue;
    // Probabilists' Gauss-Hermite nodes z and weights w (sum 1) for a standard normal in
    // ln(radius); node 0 is the centre, so population 0 is the plain model's particle moved.
    static constexpr double k3z[] = {0.0, -1.7320508075688772, 1.7320508075688772};
    static constexpr double k3w[] = {2.0 / 3.0, 1.0 / 6.0, 1.0 / 6.0};
    static constexpr double k5z[] = {0.0, -1.3556261799742659, 1.3556261799742659, -2.8569700138728056,
                                     2.8569700138728056};
    static constexpr double k5w[] = {0.53333333333333333, 0.22207592200561265, 0.22207592200561265,
                                     0.011257411327720691, 0.011257411327720691};
    const int n_pop = effects_.particle_size_populations;
    const double* z = n_pop == 3 ? k3z : k5z;
    const double* w = n_pop == 3 ? k3w : k5w;
    // Median so that sum w / R_p = 1 / R (Sauter mean = R): the total area is the cell's.
    double inv_scale_sum = 0.0;
    for (int p = 0; p < n_pop; ++p) inv_scale_sum += w[p] * std::exp(-sigma * z[p]);
    pop_scale_[side].resize(n_pop);
    pop_weight_[side].resize(n_pop);
    for (int p = 0; p < n_pop; ++p) {
      pop_scale_[side][p] = inv_scale_sum * std::exp(sigma * z[p]);
      pop_weight_[side][p] = w[p];
    }
    n_pop_[side] = n_pop;
    pop_cs0_[side] = n_;
    n_ += (n_pop - 1) * nodes_[side] * mesh_.n_r;
    pop_j0_[side] = n_;
    n_ += (n_pop - 1) * nodes_[side];
  }

}

// Cell widths, porosities, transport efficiencies and surface areas per x cell and population.
void DfnModel::layout_regions() {
  dx_.resize(nx_);
  eps_.resize(nx_);
  te_.resize(nx_);
  a_.resize(nx_);
  for (int k = 0; k < nx_; ++k) {
    if (k < mesh_.n_neg) {
      dx_[k] = cell_.negative.thickness_m / mesh_.n_neg;
      eps_[k] = cell_.negative.porosity;
      te_[k] = cell_.negative.transport_efficiency;
      a_[k] = cell_.negative.surface_area_per_volume_m();
    } else if (k < mesh_.n_neg + mesh_.n_sep) {
      dx_[k] = cell_.separator.thickness_m / mesh_.n_sep;
      eps_[k] = cell_.separator.porosity;
      te_[k] = cell_.separator.transport_efficiency;
      a_[k] = 0.0;
    } else {
      dx_[k] = cell_.positive.thickness_m / mesh_.n_pos;
      eps_[k] = cell_.positive.porosity;
      te_[k] = cell_.positive.transport_efficiency;
      a_[k] = cell_.positive.surface_area_per_volume_m();
    }
  }
  for (int side = 0; side < 2; ++side) {
    const ElectrodeParameters& el = side == 0 ? cell_.negative : cell_.positive;
    a_pop_[side].assign(n_pop_[side], 0.0);
    for (int p = 0; p < n_pop_[side]; ++p)
      a_pop_[side][p] = 3.0 * el.solid_fraction * pop_weight_[side][p] / (el.particle_radius_m * pop_scale_[side][p]);
    if (n_pop_[side] > 1) {  // a_ of the electrode's cells becomes population 0's
      const int k0 = side == 0 ? 0 : mesh_.n_neg + mesh_.n_sep, k1 = side == 0 ? mesh_.n_neg : nx_;
      for (int k = k0; k < k1; ++k) a_[k] = a_pop_[side][0];
    }
  }
}

void DfnModel::layout_shells() {
  const int nr = mesh_.n_r;
  const int n_geom = n_pop_[0] + n_pop_[1];
  shell_vol_.resize(n_geom * nr);
  face_r2_.resize(n_geom * (nr + 1));
  // Shells are finer towards the surface, where the concentration gradient is steepest:
  // face i sits at R f(i/n) with f(s) = s + b s (1 - s), so the surface shell is (1 - b)
  // times and the centre shell (1 + b) times the uniform width.
  constexpr double kSurfaceRefinement = 0.6;
  center_dist_.resize(n_geom * (nr - 1));
  surface_half_.resize(n_geom);
  for (int side = 0; side < n_geom; ++side) {
    const double radius = side < n_pop_[0] ? cell_.negative.particle_radius_m * pop_scale_[0][side]
                                           : cell_.positive.particle_radius_m * pop_scale_[1][side - n_pop_[0]];
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
}

// The residual's mass-matrix diagonal and the absolute-tolerance scale of each state.
void DfnModel::set_masses_and_scales() {
  const int nr = mesh_.n_r;
  mass_.assign(n_, 0.0);
  atol_scale_.assign(n_, 1.0);
  for (int k = 0; k < nx_; ++k) {
    mass_[idx_ce(k)] = eps_[k] * dx_[k];
    atol_scale_[idx_ce(k)] = cell_.initial_electrolyte_mol_m3;
  }
  for (int e = 0; e < ne_; ++e) {
    const double cmax =
        e < mesh_.n_neg ? cell_.negative.max_concentration_mol_m3 : cell_.positive.max_concentration_mol_m3;
    for (int p = 0; p < n_populations(e); ++p) {
      const int side = geom(e, p);
      for (int r = 0; r < nr; ++r) {
        mass_[idx_cs_pop(e, p, r)] = shell_vol_[side * nr + r];
        atol_scale_[idx_cs_pop(e, p, r)] = cmax;
      }
    }
  }
  mass_[idx_film()] = 1.0;
  atol_scale_[idx_film()] = std::max(cell_.side.initial_film_resistance_ohm_m2, 1e-3);
  mass_[idx_charge()] = 1.0;
  atol_scale_[idx_charge()] = std::max(cell_.nominal_capacity_ah, 1.0);
  if (idx_hyst_ >= 0) {
    mass_[idx_hyst_] = 1.0;
    atol_scale_[idx_hyst_] = 1e-2;  // resolves 0.1 uV at atol 1e-8 (V scale of the gap)
  }
  if (idx_temp_ >= 0) {
    mass_[idx_temp_] = heat_capacity_j_k_;  // the row is C dT/dt = Q - h (T - T_amb), in W
    atol_scale_[idx_temp_] = temperature_k_;
    // The heat sums are small differences of large products (reaction current x potentials
    // of 3 V), so their Newton residue is far above 1e-8 W/m2: a tolerance that tight makes
    // the consistent initialisation fail. They only feed the temperature; 1e-2 W/m2 (1e-3 of
    // the heat at 1C) moves the end temperature of a 2C discharge by 10 uK against 1e-3 W/m2.
    for (int k = 0; k < nx_; ++k) atol_scale_[idx_heat_sum(k)] = 1e6;
  }
}

double DfnModel::arrhenius(double activation_j_mol, double temperature_k) const {
  return std::exp(activation_j_mol / kGas_j_mol_k *
                  (1.0 / cell_.thermal.reference_temperature_k - 1.0 / temperature_k));
}

template <typename T>
T DfnModel::arrhenius(double activation_j_mol, const T& temperature_k) const {
  return exp(T(activation_j_mol / kGas_j_mol_k) * (T(1.0 / cell_.thermal.reference_temperature_k) - 1.0 / temperature_k));
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
    for (int p = 0; p < n_populations(e); ++p) {
      for (int r = 0; r < mesh_.n_r; ++r) y[idx_cs_pop(e, p, r)] = c;
      y[idx_j_pop(e, p)] = 0.0;
    }
    y[idx_phis(e)] = neg ? 0.0 : up - un;
  }
  y[idx_current()] = 0.0;
  y[idx_film()] = r_film;
  y[idx_charge()] = 0.0;
  if (idx_hyst_ >= 0) y[idx_hyst_] = effects_.hysteresis_initial_branch * effects_.hysteresis_v;
  if (idx_temp_ >= 0) y[idx_temp_] = temperature_k_;  // starts at ambient; heat sums are algebraic
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

void DfnModel::set_side_reaction_enabled(bool on) {
  if (on && n_pop_[0] > 1) throw InputError("particle_size_negative: not available together with the side reaction");
  cell_.side.enabled = on;
}

double DfnModel::film_growth_factor(const SideReactionParameters& s) {
  return s.film_growth_scale * (s.molar_mass_kg_mol / (s.density_kg_m3 * kFaradayC_mol * s.film_conductivity_s_m));
}

template <typename T>
T DfnModel::side_current(const T& phis, const T& phie, const T& j, const T& r, const T& minus_alpha_f) const {
  const auto& s = cell_.side;
  const T eta_s = phis - phie - s.reference_potential_v - j * r;
  return -s.exchange_current_a_m2 * exp(clamp_between(minus_alpha_f * eta_s, -60.0, 60.0));
}

// One evaluation of the residual g(t, y): the temperature terms shared by its rows, the heat
// sums, and one member per group of rows, in the order eval_g calls them.
template <typename T>
struct DfnResidual {
  const DfnModel& m;
  const T* y;
  T* g;
  const bool report_heat;
  const T current, i_app, r_film;
  const bool side_on, temp_dep, thermal, want_heat;
  const T temp;
  T f_rt{}, nu{}, half_f{}, minus_alpha_f_side{};
  T arr_de = T(1.0), arr_ke = T(1.0);
  T q_joule = T(0.0), q_reaction = T(0.0), q_reversible = T(0.0), p_chemical = T(0.0);  // W/m2
  T js_weighted_sum = T(0.0);

  // Temperature terms are evaluated only when they can differ from the reference; otherwise
  // every expression is the isothermal model's own (bit-for-bit the same residual).
  DfnResidual(const DfnModel& model, const T* y_in, T* g_out, bool heat_wanted)
      : m(model), y(y_in), g(g_out), report_heat(heat_wanted), current(y_in[model.idx_current()]),
        i_app(current / model.cell_.electrode_area_m2),  // A/m2, positive = discharge
        r_film(y_in[model.idx_film()]), side_on(model.cell_.side.enabled), temp_dep(model.temperature_dependent_),
        thermal(model.idx_temp_ >= 0), want_heat(thermal || heat_wanted),
        temp(thermal ? y_in[model.idx_temp_] : T(model.temperature_k_)) {
    const double tplus = m.cell_.electrolyte.transference_number;
    const double f_rt_ref = m.f_rt_;
    f_rt = temp_dep ? T(kFaradayC_mol / kGas_j_mol_k) / temp : T(f_rt_ref);
    nu = temp_dep ? T(2.0 * (1.0 - tplus)) / f_rt : T(2.0 * (1.0 - tplus) / f_rt_ref);  // V, without the TDF
    half_f = temp_dep ? T(0.5) * f_rt : T(0.5 * f_rt_ref);
    minus_alpha_f_side =
        temp_dep ? T(-m.cell_.side.transfer_coefficient) * f_rt : T(-m.cell_.side.transfer_coefficient * f_rt_ref);
    if (temp_dep) {
      arr_de = m.arrhenius(m.cell_.electrolyte.diffusivity_activation_j_mol, temp);
      arr_ke = m.arrhenius(m.cell_.electrolyte.conductivity_activation_j_mol, temp);
    }
  }

  T d_eff(const T& ce, int k) const {
    const T d = apply(*m.cell_.electrolyte.diffusivity_m2_s, ce) * m.te_[k];
    return temp_dep ? d * arr_de : d;
  }
  T kappa_eff(const T& ce, int k) const {
    const T kap = apply(*m.cell_.electrolyte.conductivity_s_m, ce) * m.te_[k];
    return temp_dep ? kap * arr_ke : kap;
  }
  // The solid diffusivity's factor on a face between shells of concentrations a and b.
  static T diffusivity_factor(const ScalarFunction& f, const T& a, const T& b, double cmax) {
    return apply(f, clamp_between((0.5 / cmax) * (a + b), 0.0, 1.0));
  }
  void add_heat(int k, const T& q, T& total) {
    if (thermal) g[m.idx_heat_sum(k)] = g[m.idx_heat_sum(k)] - q;
    if (report_heat) total = total + q;
  }

  // Heat rows: running sum S_k = S_(k-1) + q_k, with q_k subtracted as it is found.
  void heat_rows() {
    if (thermal)
      for (int k = 0; k < m.nx_; ++k)
        g[m.idx_heat_sum(k)] = y[m.idx_heat_sum(k)] - (k > 0 ? y[m.idx_heat_sum(k - 1)] : T(0.0));
  }
  void electrolyte();
  void electrode(int e);
  void particle(int e, int pop, const T& j, const T& phis, const T& phie, const T& ce, const T& arr_ds);
  T shells(int e, int pop, const ElectrodeParameters& p, const T& flux_out, const T& arr_ds);
  T resistive_reactant(int e, int pop, const ElectrodeParameters& p) const;
  void closing_rows(double t, HeatRates* heat);
};

// Electrolyte: concentration flux and ionic current on the internal faces.
template <typename T>
void DfnResidual<T>::electrolyte() {
  const int nn = m.mesh_.n_neg, ns = m.mesh_.n_sep, nx = m.nx_;
  const double tplus = m.cell_.electrolyte.transference_number;
  T flux_left = T(0.0), ie_left = T(0.0);
  T ce_k = clamp_above(y[m.idx_ce(0)], 1e-3);
  T d_k = d_eff(ce_k, 0);
  T kap_k = kappa_eff(ce_k, 0);
  // Ideal solution (no thermodynamic factor): i_e = -kappa grad(phi_e - nu ln c_e), written
  // with the potential psi = phi_e - nu ln c_e. With a factor TDF(c_e) the diffusion term is
  // nu TDF grad ln c_e, TDF taken on each face as the mean of its two cells (exact for a
  // constant factor).
  const ScalarFunction* tdf = m.cell_.electrolyte.thermodynamic_factor.get();
  T lnc_k = log(ce_k);
  T tdf_k = tdf ? apply(*tdf, ce_k) : T(1.0);
  T psi_k = y[m.idx_phie(0)] - nu * lnc_k;
  const auto& dx = m.dx_;
  for (int k = 0; k < nx; ++k) {
    T flux_right = T(0.0), ie_right = T(0.0);
    T ce_n{}, d_n{}, kap_n{}, psi_n{}, lnc_n{}, tdf_n{};
    if (k + 1 < nx) {
      ce_n = clamp_above(y[m.idx_ce(k + 1)], 1e-3);
      d_n = d_eff(ce_n, k + 1);
      kap_n = kappa_eff(ce_n, k + 1);
      lnc_n = log(ce_n);
      psi_n = y[m.idx_phie(k + 1)] - nu * lnc_n;
      // Series resistance of the two half cells: exact at region interfaces.
      const T rd = dx[k] / (2.0 * d_k) + dx[k + 1] / (2.0 * d_n);
      const T rk = dx[k] / (2.0 * kap_k) + dx[k + 1] / (2.0 * kap_n);
      flux_right = (y[m.idx_ce(k + 1)] - y[m.idx_ce(k)]) / rd;
      if (tdf) {
        tdf_n = apply(*tdf, ce_n);
        const T diffusion_v = nu * (0.5 * (tdf_k + tdf_n)) * (lnc_n - lnc_k);
        ie_right = -((y[m.idx_phie(k + 1)] - y[m.idx_phie(k)]) - diffusion_v) / rk;
      } else {
        ie_right = -(psi_n - psi_k) / rk;
      }
      // Ohmic heat of the ionic current, -i_e grad(phi_e), including the diffusion potential.
      if (want_heat) add_heat(k, ie_right * (y[m.idx_phie(k)] - y[m.idx_phie(k + 1)]), q_joule);
    }
    T source = T(0.0);  // volumetric reaction current J (A/m3) times dx
    if (m.a_[k] > 0.0) {
      const int e = k < nn ? k : k - ns;
      T a_j = m.a_[k] * y[m.idx_j(e)];
      for (int pop = 1; pop < m.n_populations(e); ++pop) a_j = a_j + m.a_pop_[m.side_of(e)][pop] * y[m.idx_j_pop(e, pop)];
      source = a_j * dx[k];
    }
    g[m.idx_ce(k)] = flux_right - flux_left + (1.0 - tplus) / kFaradayC_mol * source;
    g[m.idx_phie(k)] = ie_right - ie_left - source;
    flux_left = flux_right;
    ie_left = ie_right;
    if (k + 1 < nx) {
      ce_k = ce_n; d_k = d_n; kap_k = kap_n; psi_k = psi_n; lnc_k = lnc_n; tdf_k = tdf_n;
    }
  }
}

// Electrode node e: solid potential, kinetics, particles.
template <typename T>
void DfnResidual<T>::electrode(int e) {
  const int nn = m.mesh_.n_neg, ns = m.mesh_.n_sep;
  const bool neg = e < nn;
  const int k = neg ? e : e + ns;
  const ElectrodeParameters& p = neg ? m.cell_.negative : m.cell_.positive;
  const int first = neg ? 0 : nn, last = neg ? nn - 1 : m.ne_ - 1;
  const double sigma = p.conductivity_eff_s_m;
  const double h = m.dx_[k];
  // Solid current on the faces (positive in +x): I/A at the current collectors, 0 at the separator.
  const T is_left = e == first ? (neg ? i_app : T(0.0)) : -sigma * (y[m.idx_phis(e)] - y[m.idx_phis(e - 1)]) / h;
  const T is_right = e == last ? (neg ? T(0.0) : i_app) : -sigma * (y[m.idx_phis(e + 1)] - y[m.idx_phis(e)]) / h;
  const T j = y[m.idx_j(e)];
  T a_j = m.a_[k] * j;  // reaction current per volume (A/m3), all populations
  for (int pop = 1; pop < m.n_populations(e); ++pop) a_j = a_j + m.a_pop_[m.side_of(e)][pop] * y[m.idx_j_pop(e, pop)];
  g[m.idx_phis(e)] = is_right - is_left + a_j * h;
  if (want_heat && e != last) add_heat(k, is_right * (y[m.idx_phis(e)] - y[m.idx_phis(e + 1)]), q_joule);

  const T arr_ds = temp_dep ? m.arrhenius(p.diffusivity_activation_j_mol, temp) : T(1.0);
  const T phis = y[m.idx_phis(e)], phie = y[m.idx_phie(k)];
  const T ce = clamp_above(y[m.idx_ce(k)], 1e-3);
  for (int pop = 0; pop < m.n_populations(e); ++pop) particle(e, pop, j, phis, phie, ce, arr_ds);
}

// The radial finite volumes of one particle (rows of its shells); returns the drop of
// concentration from the last shell's centre to the surface.
template <typename T>
T DfnResidual<T>::shells(int e, int pop, const ElectrodeParameters& p, const T& flux_out, const T& arr_ds) {
  const int nr = m.mesh_.n_r;
  const int side = m.geom(e, pop);
  const double ds = p.solid_diffusivity_m2_s;
  const auto& face_r2 = m.face_r2_;
  const auto& center_dist = m.center_dist_;
  const double cmax = p.max_concentration_mol_m3;
  // A stoichiometry-dependent D is taken on each face, at the mean concentration of its two
  // shells (flux form: both shells see the same flux, so lithium is conserved exactly).
  const ScalarFunction* d_factor = p.solid_diffusivity_factor.get();
  T factor_left = T(1.0);
  for (int r = 0; r < nr; ++r) {
    const T c = y[m.idx_cs_pop(e, pop, r)];
    T in_right = r + 1 < nr ? face_r2[side * (nr + 1) + r + 1] * ds * (y[m.idx_cs_pop(e, pop, r + 1)] - c) /
                                  center_dist[side * (nr - 1) + r]
                            : -face_r2[side * (nr + 1) + nr] * flux_out;
    T in_left = r > 0 ? face_r2[side * (nr + 1) + r] * ds * (c - y[m.idx_cs_pop(e, pop, r - 1)]) /
                            center_dist[side * (nr - 1) + r - 1]
                      : T(0.0);
    if (d_factor) {
      const T factor_right = r + 1 < nr ? diffusivity_factor(*d_factor, c, y[m.idx_cs_pop(e, pop, r + 1)], cmax) : T(1.0);
      if (r + 1 < nr) in_right = in_right * factor_right;
      if (r > 0) in_left = in_left * factor_left;
      factor_left = factor_right;
    }
    if (temp_dep) {  // diffusive faces only: the surface flux is set by the reaction
      if (r + 1 < nr) in_right = in_right * arr_ds;
      if (r > 0) in_left = in_left * arr_ds;
    }
    g[m.idx_cs_pop(e, pop, r)] = in_right - in_left;
  }
  const double surface_half = m.surface_half_[side];
  T surface_drop = temp_dep ? surface_half * flux_out / (ds * arr_ds) : surface_half * flux_out / ds;
  if (d_factor) {  // the outer half shell at the last shell's D
    const T c_last = y[m.idx_cs_pop(e, pop, nr - 1)];
    surface_drop = surface_drop / diffusivity_factor(*d_factor, c_last, c_last, cmax);
  }
  return surface_drop;
}

// The resistive reactant's resistance (ohm m2) of a cathode particle at its mean stoichiometry.
template <typename T>
T DfnResidual<T>::resistive_reactant(int e, int pop, const ElectrodeParameters& p) const {
  const int nr = m.mesh_.n_r;
  const int side = m.geom(e, pop);
  const double radius = p.particle_radius_m * m.pop_scale_[m.side_of(e)][pop];
  const double per_volume = 3.0 / (radius * radius * radius * p.max_concentration_mol_m3);
  T x_mean = T(0.0);
  for (int r = 0; r < nr; ++r) x_mean = x_mean + y[m.idx_cs_pop(e, pop, r)] * (m.shell_vol_[side * nr + r] * per_volume);
  const T r = m.effects_.resistive_reactant_positive_ohm_m2 * apply(*m.reactant_factor_, x_mean);
  const double ea = m.effects_.resistive_reactant_positive_ea_j_mol;
  // A conductivity activated by Ea: the resistance falls as the cell warms (arrhenius of -Ea).
  return temp_dep && ea > 0.0 ? r * m.arrhenius(-ea, temp) : r;
}

// Population pop of node e's particles: finite volumes in r, the molar flux out of the surface
// from the intercalation part, and the kinetics at the surface.
template <typename T>
void DfnResidual<T>::particle(int e, int pop, const T& j, const T& phis, const T& phie, const T& ce,
                              const T& arr_ds) {
  const int nr = m.mesh_.n_r;
  const bool neg = e < m.mesh_.n_neg;
  const int k = neg ? e : e + m.mesh_.n_sep;
  const ElectrodeParameters& p = neg ? m.cell_.negative : m.cell_.positive;
  const double h = m.dx_[k];
  const T jp = pop == 0 ? j : y[m.idx_j_pop(e, pop)];
  T js = T(0.0);
  if (neg && side_on) js = m.side_current(phis, phie, jp, r_film, minus_alpha_f_side);
  const T flux_out = (jp - js) / kFaradayC_mol;
  const double cmax = p.max_concentration_mol_m3;
  const T surface_drop = shells(e, pop, p, flux_out, arr_ds);
  const T c_surf = clamp_between(y[m.idx_cs_pop(e, pop, nr - 1)] - surface_drop, 1e-6 * cmax, (1.0 - 1e-6) * cmax);
  T i0 = p.i0_coefficient * sqrt(ce * c_surf * (cmax - c_surf));
  if (temp_dep) i0 = i0 * m.arrhenius(p.rate_activation_j_mol, temp);
  T ocp = apply(*p.ocp_v, c_surf / cmax);
  T dudt = T(0.0);
  if ((temp_dep || want_heat) && p.entropic_v_k) dudt = apply(*p.entropic_v_k, c_surf / cmax);
  if (temp_dep && p.entropic_v_k) ocp = ocp + (temp - m.cell_.thermal.reference_temperature_k) * dudt;
  T eta = phis - phie - ocp;
  if (neg) eta = eta - jp * r_film;
  if (!neg && m.effects_.resistive_reactant_on()) eta = eta - jp * resistive_reactant(e, pop, p);
  // Saturating the exponent keeps wild Newton trial states (consistent initialisation after
  // a large current step) finite; converged states are far inside the limit.
  g[m.idx_j_pop(e, pop)] = jp - (2.0 * i0 * sinh(clamp_between(half_f * eta, -60.0, 60.0)) + js);
  if (neg) js_weighted_sum = js_weighted_sum + js * h;
  if (want_heat) {
    // Irreversible: the whole drop phi_s - phi_e - U (kinetics and film); reversible: j T dU/dT.
    const T ajh = (pop == 0 ? m.a_[k] : m.a_pop_[m.side_of(e)][pop]) * h * jp;
    add_heat(k, ajh * (phis - phie - ocp), q_reaction);
    if (p.entropic_v_k) add_heat(k, ajh * temp * dudt, q_reversible);
    if (report_heat) p_chemical = p_chemical - ajh * ocp;
  }
}

// Ground, current control, film, charge, hysteresis and temperature rows.
template <typename T>
void DfnResidual<T>::closing_rows(double t, HeatRates* heat) {
  const auto& cell = m.cell_;
  const auto& fx = m.effects_;
  const int idx_hyst = m.idx_hyst_;
  // Ground: the negative current collector is at 0 V (replaces one redundant charge balance).
  const double h_n = m.dx_[0], h_p = m.dx_[m.nx_ - 1];
  g[m.idx_phie(0)] = y[m.idx_phis(0)] + i_app * (0.5 * h_n / cell.negative.conductivity_eff_s_m);

  T v_terminal = y[m.idx_phis(m.ne_ - 1)] - i_app * (0.5 * h_p / cell.positive.conductivity_eff_s_m) -
                 y[m.idx_phis(0)] - i_app * (0.5 * h_n / cell.negative.conductivity_eff_s_m) -
                 fx.contact_resistance_ohm * current;
  if (idx_hyst >= 0) v_terminal = v_terminal + y[idx_hyst];
  switch (m.control_.kind) {
    case ControlKind::current:
    case ControlKind::profile:
      g[m.idx_current()] = current - m.current_setpoint_a(t);
      break;
    case ControlKind::voltage:
      g[m.idx_current()] = v_terminal - m.control_.value;
      break;
  }
  const T mean_js = js_weighted_sum / cell.negative.thickness_m;
  g[m.idx_film()] = m.film_frozen_ || !side_on ? T(0.0) : -m.film_growth_factor() * mean_js;
  g[m.idx_charge()] = current / 3600.0;

  if (idx_hyst >= 0) {
    // dh/dt = -(kappa |I| / Q) (h + H sign(I)): h follows the charge moved, not the time.
    const T abs_i = fw::value_of(current) < 0.0 ? -current : current;
    const double rate = fx.hysteresis_rate_per_soc / (3600.0 * cell.nominal_capacity_ah);
    g[idx_hyst] = -rate * (fx.hysteresis_v * current + abs_i * y[idx_hyst]);
  }
  if (!want_heat) return;
  const double area = cell.electrode_area_m2;
  const double r_collector = 0.5 * h_n / cell.negative.conductivity_eff_s_m +
                             0.5 * h_p / cell.positive.conductivity_eff_s_m;  // ohm m2
  const T q_lumped = area * r_collector * i_app * i_app + fx.contact_resistance_ohm * current * current;  // W
  const T q_hyst = idx_hyst >= 0 ? -current * y[idx_hyst] : T(0.0);
  if (thermal)
    g[m.idx_temp_] = area * y[m.idx_heat_sum(m.nx_ - 1)] + q_lumped + q_hyst -
                     fx.thermal_h_w_per_k * (temp - m.temperature_k_);
  if constexpr (std::is_same_v<T, double>) {
    if (heat) {
      heat->joule_w = area * q_joule + q_lumped;
      heat->reaction_w = area * q_reaction;
      heat->reversible_w = area * q_reversible;
      heat->hysteresis_w = q_hyst;
      heat->chemical_power_w = area * p_chemical;
      heat->electrical_power_w = current * v_terminal;
    }
  }
}

template <typename T>
void DfnModel::eval_g(double t, const T* y, T* g, HeatRates* heat) const {
  DfnResidual<T> r(*this, y, g, heat != nullptr);
  r.heat_rows();
  r.electrolyte();
  for (int e = 0; e < ne_; ++e) r.electrode(e);
  r.closing_rows(t, heat);
}

double DfnModel::terminal_voltage_v(const double* y) const {
  const double i_app = y[idx_current()] / cell_.electrode_area_m2;
  const double v = y[idx_phis(ne_ - 1)] - i_app * (0.5 * dx_[nx_ - 1] / cell_.positive.conductivity_eff_s_m) -
                   y[idx_phis(0)] - i_app * (0.5 * dx_[0] / cell_.negative.conductivity_eff_s_m) -
                   effects_.contact_resistance_ohm * y[idx_current()];
  return idx_hyst_ >= 0 ? v + y[idx_hyst_] : v;
}

HeatRates DfnModel::heat_rates(const double* y) const {
  std::vector<double> g(static_cast<size_t>(n_));
  HeatRates h;
  eval_g(0.0, y, g.data(), &h);
  return h;
}

double DfnModel::mean_side_current_a_m2(const double* y) const {
  if (!cell_.side.enabled) return 0.0;
  const double minus_alpha_f = -cell_.side.transfer_coefficient *
                               (temperature_dependent_ ? kFaradayC_mol / kGas_j_mol_k / temperature_k(y) : f_rt_);
  double sum = 0.0;
  for (int e = 0; e < mesh_.n_neg; ++e)
    sum += side_current(y[idx_phis(e)], y[idx_phie(e)], y[idx_j(e)], y[idx_film()], minus_alpha_f) * dx_[e];
  return sum / cell_.negative.thickness_m;
}

void DfnModel::film_row_jacobian(const double* y, std::vector<std::pair<int, double>>& out) const {
  out.clear();
  const double r = y[idx_film()];
  const double f_rt = temperature_dependent_ ? kFaradayC_mol / kGas_j_mol_k / temperature_k(y) : f_rt_;
  const double alpha_f = cell_.side.transfer_coefficient * f_rt;
  const double scale = film_frozen_ || !cell_.side.enabled ? 0.0 : -film_growth_factor() / cell_.negative.thickness_m;
  double d_r = 0.0, d_temp = 0.0;
  for (int e = 0; e < mesh_.n_neg; ++e) {
    const double j = y[idx_j(e)];
    const double js = side_current(y[idx_phis(e)], y[idx_phie(e)], j, r, -alpha_f);
    const double eta_s = y[idx_phis(e)] - y[idx_phie(e)] - cell_.side.reference_potential_v - j * r;
    const double arg = -alpha_f * eta_s;
    const bool saturated = arg <= -60.0 || arg >= 60.0;  // as in side_current()
    const double w = saturated ? 0.0 : scale * dx_[e] * (-alpha_f) * js;  // d js / d eta_s = -alpha f js
    out.emplace_back(idx_phis(e), w);
    out.emplace_back(idx_phie(e), -w);
    out.emplace_back(idx_j(e), -w * r);
    d_r += -w * j;
    // f = F / (R T): d(arg)/dT = -arg / T.
    if (idx_temp_ >= 0 && !saturated) d_temp += scale * dx_[e] * js * (-arg / temperature_k(y));
  }
  out.emplace_back(idx_film(), d_r);
  // The temperature column is dense in the pattern, so the film row's entry must be written.
  if (idx_temp_ >= 0) out.emplace_back(idx_temp_, d_temp);
}

double DfnModel::lithium_inventory_mol(const double* y) const {
  const int nn = mesh_.n_neg, ns = mesh_.n_sep, nr = mesh_.n_r;
  double total = 0.0;
  for (int k = 0; k < nx_; ++k) total += eps_[k] * y[idx_ce(k)] * dx_[k];
  for (int e = 0; e < ne_; ++e) {
    const bool neg = e < nn;
    const int k = neg ? e : e + ns;
    const ElectrodeParameters& p = neg ? cell_.negative : cell_.positive;
    for (int pop = 0; pop < n_populations(e); ++pop) {
      const int side = geom(e, pop);
      const double radius = p.particle_radius_m * pop_scale_[side_of(e)][pop];
      double moles_per_particle_scaled = 0.0;
      for (int r = 0; r < nr; ++r) moles_per_particle_scaled += y[idx_cs_pop(e, pop, r)] * shell_vol_[side * nr + r];
      const double fraction = p.solid_fraction * pop_weight_[side_of(e)][pop];
      total += fraction * dx_[k] * moles_per_particle_scaled * 3.0 / (radius * radius * radius);
    }
  }
  return total * cell_.electrode_area_m2;
}

double DfnModel::mean_stoich(const double* y, bool negative) const {
  const int nr = mesh_.n_r;
  const int first = negative ? 0 : mesh_.n_neg, count = negative ? mesh_.n_neg : mesh_.n_pos;
  const ElectrodeParameters& p = negative ? cell_.negative : cell_.positive;
  double sum = 0.0;
  for (int e = first; e < first + count; ++e) {
    for (int pop = 0; pop < n_populations(e); ++pop) {
      const int side = geom(e, pop);
      const double radius = p.particle_radius_m * pop_scale_[side_of(e)][pop];
      const double r3 = radius * radius * radius;
      const double weight = pop_weight_[side_of(e)][pop];
      for (int r = 0; r < nr; ++r) sum += weight * (y[idx_cs_pop(e, pop, r)] * shell_vol_[side * nr + r] * 3.0 / r3);
    }
  }
  return sum / count / p.max_concentration_mol_m3;
}

double DfnModel::surface_stoich(const double* y, int e) const {
  const bool neg = e < mesh_.n_neg;
  const ElectrodeParameters& p = neg ? cell_.negative : cell_.positive;
  return y[idx_cs(e, mesh_.n_r - 1)] / p.max_concentration_mol_m3;
}

double DfnModel::lithium_loss_mol(double r_film, double r_film_start) const {
  if (!cell_.side.enabled) return 0.0;
  // dR/dt = -factor mean(js); Li loss rate = -A L_n a_n mean(js) / F. The factor carries
  // film_growth_scale, so dividing by it gives the lithium whatever the scale (which is > 0).
  const double per_r = cell_.electrode_area_m2 * cell_.negative.thickness_m *
                       cell_.negative.surface_area_per_volume_m() / (kFaradayC_mol * film_growth_factor());
  return (r_film - r_film_start) * per_r;
}

template void DfnModel::eval_g<double>(double, const double*, double*, HeatRates*) const;
template void DfnModel::eval_g<fw::Dual<double>>(double, const fw::Dual<double>*, fw::Dual<double>*, HeatRates*) const;
template void DfnModel::eval_g<JacobianDual>(double, const JacobianDual*, JacobianDual*, HeatRates*) const;
template void DfnModel::eval_g<SparsityTracer>(double, const SparsityTracer*, SparsityTracer*, HeatRates*) const;

}  // namespace bms
