#pragma once
// Doyle-Fuller-Newman pseudo-2D cell model with the Ramadass side reaction (paper eqs 1-12),
// discretised by finite volumes in x (electrolyte, electrodes) and r (every particle).
// The DAE is written as  F(t, y, y') = M y' - g(y, t) = 0  with M diagonal (zero on the
// algebraic rows). g is templated on the scalar type so its Jacobian is exact (dual numbers).
#include <cmath>
#include <vector>

#include "bms/fw/model/dual.hpp"
#include "bms/fw/model/physical_constants.hpp"
#include "cell/cell_parameters.hpp"

namespace bms {

using fw::kFaradayC_mol;
inline constexpr double kGas_j_mol_k = fw::kGasJ_molK;

struct DfnMesh {
  int n_neg = 20;
  int n_sep = 20;
  int n_pos = 20;
  int n_r = 20;
};

// What the current row of the DAE enforces.
enum class ControlKind { current, voltage, profile };

struct Control {
  ControlKind kind = ControlKind::current;
  double value = 0.0;  // current in A (positive = discharge) or voltage in V
  // Profile: current(t) piecewise linear through (t_s[i], current_a[i]).
  const std::vector<double>* profile_t_s = nullptr;
  const std::vector<double>* profile_current_a = nullptr;
};

// Effects the plain DFN lacks, switchable in the truth model. Zero everywhere = the plain
// isothermal DFN, bit for bit (no extra states are allocated).
struct ModelEffects {
  double contact_resistance_ohm = 0.0;  // V = phi+ - phi- - R_c I
  // One-state OCV hysteresis (Plett 2004): h relaxes towards -H sign(I) at a rate proportional
  // to |I|, so it depends on the charge moved, not on time, and survives at low current.
  // V gains +h: h = +H on the charge branch, -H on the discharge branch.
  double hysteresis_v = 0.0;  // H, half the gap between the branches (0 = off)
  // Fraction of the remaining gap closed per unit of state of charge (1/capacity): 50 closes
  // 90 % of a branch change within ln(10)/50 = 4.6 % SOC (docs/results/measured-effects.md).
  double hysteresis_rate_per_soc = 50.0;
  // Initial h in units of H: +1 = on the charge branch (the cell was just charged, the
  // usual start of a discharge from full), -1 = discharge branch, 0 = between.
  double hysteresis_initial_branch = 1.0;
  // Lumped thermal model: one cell temperature, heat capacity from the cell parameters,
  // Joule + reaction + entropic heat, loss h (T - T_ambient). 0 = isothermal.
  double thermal_h_w_per_k = 0.0;
  // Positive-electrode particle-size distribution (a multi-particle model): the active
  // material of every cathode control volume is split into populations whose radii sample a
  // volume-weighted lognormal of log-space standard deviation sigma (Gauss-Hermite nodes and
  // weights). Each population has its own shells and its own reaction current; they share the
  // volume's phi_s, phi_e and c_e. The quadrature keeps the Sauter (area-weighted) mean radius
  // at the cell's R, so the electrode's surface area per volume - and with it the kinetics at
  // low rate - is unchanged; only the spread of diffusion times R^2/D is added.
  double particle_size_sigma = 0.0;           // cathode; 0 = one size (off)
  double particle_size_negative_sigma = 0.0;  // the same for the anode (not with the side reaction)
  int particle_size_populations = 3;          // quadrature nodes per electrode: 3 or 5
  // Cathode solid diffusivity as a function of the local stoichiometry (a knee profile over the
  // cell's own D(x); cell/diffusivity_profile.hpp): log10 of the factor at x = 1, 0 = off; the
  // knee stoichiometry below which the factor is 1. The radial flux takes D on each shell face.
  double diffusivity_profile_positive = 0.0;
  double diffusivity_profile_positive_knee = 0.5;
  // Resistive reactant (Thomas-Alyea 2008; Safari and Delacourt 2011 for LiFePO4): the lithiated
  // phase conducts poorly, so each cathode particle's reaction meets a resistance that grows as
  // the particle fills. An ohmic drop j R(x_mean) in the particle's overpotential, R in ohm m2 of
  // particle surface, at the particle's mean stoichiometry (the share of the reacted phase, not
  // the surface's): R = R_0 10^(s clamp((x - x_k) / (1 - x_k), 0, 1)), constant R_0 below the
  // knee x_k, s decades higher at x = 1. 0 = off.
  double resistive_reactant_positive_ohm_m2 = 0.0;
  double resistive_reactant_positive_log10 = 0.0;
  double resistive_reactant_positive_knee = 0.5;
  // The reactant's resistance follows the cell temperature, R(x, T) = R(x) exp(Ea/Rgas (1/T -
  // 1/T_ref)) with T_ref the cell's reference temperature: LiFePO4's electronic conductivity is
  // thermally activated, so a warming cell's reactant resists less. J/mol; 0 = R(x) alone.
  double resistive_reactant_positive_ea_j_mol = 0.0;

  bool hysteresis_on() const { return hysteresis_v > 0.0; }
  bool thermal_on() const { return thermal_h_w_per_k > 0.0; }
  bool particle_size_on() const { return particle_size_sigma > 0.0 || particle_size_negative_sigma > 0.0; }
  bool diffusivity_profile_on() const { return diffusivity_profile_positive != 0.0; }
  bool resistive_reactant_on() const { return resistive_reactant_positive_ohm_m2 > 0.0; }
};

// The effects a run switches on plus the cell's own (CellParameters::effects): the contact
// resistances add; the cell's hysteresis half-gap, thermal coefficient, particle-size spread and
// diffusivity profile apply where the run leaves them off, its hysteresis rate always. Every DfnModel is built with this.
ModelEffects with_cell_effects(const CellParameters& cell, ModelEffects effects);

// Heat sources of one state (W, whole cell). joule: electrolyte and solid ohmic heat,
// current-collector half cells and contact resistance; reaction: j (phi_s - phi_e - U) summed
// over the electrodes (kinetic overpotential and film drop); reversible: j T dU/dT;
// hysteresis: -I h (the energy lost around a hysteresis loop).
struct HeatRates {
  double joule_w = 0.0, reaction_w = 0.0, reversible_w = 0.0, hysteresis_w = 0.0;
  double total_w() const { return joule_w + reaction_w + reversible_w + hysteresis_w; }
  double chemical_power_w = 0.0;  // sum of j U over the electrodes: what the cell's reactions deliver
  double electrical_power_w = 0.0;  // I V at the terminals
};

template <typename T>
struct DfnResidual;  // one evaluation of DfnModel::eval_g (dfn_model.cpp)

class DfnModel {
 public:
  // temperature_k: the cell's temperature when isothermal; with the thermal effect, the
  // ambient and initial temperature. Effects that add states are fixed at construction.
  DfnModel(const CellParameters& cell, const DfnMesh& mesh, double temperature_k,
           const ModelEffects& effects = {});

  const CellParameters& cell() const { return cell_; }
  const DfnMesh& mesh() const { return mesh_; }
  int size() const { return n_; }
  int n_x() const { return nx_; }
  int n_electrode_nodes() const { return mesh_.n_neg + mesh_.n_pos; }

  // Variable layout.
  int idx_ce(int k) const { return k; }
  int idx_phie(int k) const { return nx_ + k; }
  int idx_cs(int e, int r) const { return 2 * nx_ + e * mesh_.n_r + r; }
  int idx_phis(int e) const { return cs_end_ + e; }
  int idx_j(int e) const { return cs_end_ + ne_ + e; }
  int idx_current() const { return cs_end_ + 2 * ne_; }
  int idx_film() const { return cs_end_ + 2 * ne_ + 1; }
  int idx_charge() const { return cs_end_ + 2 * ne_ + 2; }
  // Present only with the matching effect (-1 otherwise).
  int idx_hysteresis() const { return idx_hyst_; }
  int idx_temperature() const { return idx_temp_; }
  // Particle populations of electrode node e (1 without the particle-size effect). Population
  // 0 is the plain model's particle (idx_cs, idx_j); the others' states follow the effects'.
  int n_populations(int e) const { return n_pop_[side_of(e)]; }
  int idx_cs_pop(int e, int p, int r) const {
    const int s = side_of(e);
    return p == 0 ? idx_cs(e, r) : pop_cs0_[s] + ((p - 1) * nodes_[s] + local_node(e)) * mesh_.n_r + r;
  }
  int idx_j_pop(int e, int p) const {
    const int s = side_of(e);
    return p == 0 ? idx_j(e) : pop_j0_[s] + (p - 1) * nodes_[s] + local_node(e);
  }
  // Population p of an electrode: radius / the cell's radius, and share of the active volume.
  double population_radius_scale(bool negative, int p) const { return pop_scale_[negative ? 0 : 1][p]; }
  double population_volume_fraction(bool negative, int p) const { return pop_weight_[negative ? 0 : 1][p]; }
  // Running sum of the local heat over x cells 0..k (W/m2): keeps the temperature row sparse.
  int idx_heat_sum(int k) const { return idx_heat0_ + k; }
  bool is_differential(int i) const { return mass_[i] != 0.0; }
  const std::vector<double>& mass() const { return mass_; }
  const std::vector<double>& abs_tolerance_scale() const { return atol_scale_; }

  void set_control(const Control& c) { control_ = c; }
  const Control& control() const { return control_; }
  const ModelEffects& effects() const { return effects_; }
  // Changes the contact resistance (the one effect that adds no state).
  void set_contact_resistance_ohm(double r) { effects_.contact_resistance_ohm = r; }
  bool side_reaction_enabled() const { return cell_.side.enabled; }
  bool temperature_dependent() const { return temperature_dependent_; }
  void set_side_reaction_enabled(bool on);
  // When frozen, the film row becomes dR/dt = 0 (the film resistance is an input).
  void set_film_frozen(bool frozen) { film_frozen_ = frozen; }

  // Initial state at rest (algebraic part is a guess; the solver makes it consistent).
  std::vector<double> initial_state(double stoich_neg, double stoich_pos, double ce_mol_m3,
                                    double r_film_ohm_m2) const;

  // heat (doubles only): receives the heat sources of y, whether or not the thermal state exists.
  template <typename T>
  void eval_g(double t, const T* y, T* g, HeatRates* heat = nullptr) const;

  double current_setpoint_a(double t) const;

  // Derived outputs of a state.
  double terminal_voltage_v(const double* y) const;
  double temperature_k(const double* y) const { return idx_temp_ >= 0 ? y[idx_temp_] : temperature_k_; }
  double hysteresis_voltage_v(const double* y) const { return idx_hyst_ >= 0 ? y[idx_hyst_] : 0.0; }
  // Heat sources recomputed from the state (the DAE carries the same sum in its heat rows).
  HeatRates heat_rates(const double* y) const;
  double heat_capacity_j_k() const { return heat_capacity_j_k_; }
  double mean_side_current_a_m2(const double* y) const;  // mean over the anode of j_s (A/m2)
  double lithium_inventory_mol(const double* y) const;   // solid + electrolyte
  double mean_stoich(const double* y, bool negative) const;
  double surface_stoich(const double* y, int e) const;
  // Lithium lost to the side reaction implied by the film growth since r0 (exact for the
  // lumped film: both integrate the same mean side-reaction current).
  double lithium_loss_mol(double r_film_ohm_m2, double r_film_start_ohm_m2) const;
  // d(mean j_s)/d(variable) for the film row, whose column pattern is dense.
  void film_row_jacobian(const double* y, std::vector<std::pair<int, double>>& out) const;
  int film_row() const { return idx_film(); }
  double film_growth_factor() const { return film_growth_factor(cell_.side); }  // dR/dt = -factor * mean(j_s)
  // The same for any side-reaction set: film_growth_scale M / (rho F kappa), ohm m2 per (A/m2 s)
  // of pore-wall current.
  static double film_growth_factor(const SideReactionParameters& s);

 private:
  template <typename T> friend struct DfnResidual;
  // The constructor's steps, in this order: each uses what the ones before it laid out.
  void layout_populations();
  void layout_regions();
  void layout_shells();
  void set_masses_and_scales();
  template <typename T>
  T side_current(const T& phis, const T& phie, const T& j, const T& r, const T& minus_alpha_f) const;
  double arrhenius(double activation_j_mol, double temperature_k) const;
  template <typename T> T arrhenius(double activation_j_mol, const T& temperature_k) const;

  CellParameters cell_;
  DfnMesh mesh_;
  double temperature_k_;
  double f_rt_;
  int nx_, ne_, cs_end_, n_;
  int idx_hyst_ = -1, idx_temp_ = -1, idx_heat0_ = -1;
  // Per electrode side (0 = anode, 1 = cathode): populations, where their extra states start,
  // electrode nodes, radius scales, volume fractions, surface area per volume (1/m).
  int n_pop_[2] = {1, 1}, pop_cs0_[2] = {-1, -1}, pop_j0_[2] = {-1, -1}, nodes_[2] = {0, 0};
  std::vector<double> pop_scale_[2], pop_weight_[2], a_pop_[2];
  int side_of(int e) const { return e < mesh_.n_neg ? 0 : 1; }
  int local_node(int e) const { return e < mesh_.n_neg ? e : e - mesh_.n_neg; }
  // Geometry index of a particle: anode populations first (0 = the plain anode particle), so
  // without the effect the anode is 0 and the cathode 1, as before.
  int geom(int e, int p) const { return e < mesh_.n_neg ? p : n_pop_[0] + p; }
  // Off when isothermal at the reference temperature: then no temperature term is evaluated
  // and the residual is the isothermal model's, bit for bit.
  bool temperature_dependent_ = false;
  double heat_capacity_j_k_ = 0.0;
  std::vector<double> dx_, eps_, te_, a_;  // per x cell (a_ = 0 in separator)
  std::vector<double> shell_vol_, face_r2_;  // per geometry (n_r, n_r + 1 each)
  std::vector<double> center_dist_;          // per geometry, n_r - 1 distances between shell centres
  std::vector<double> surface_half_;         // per geometry, centre of the last shell to the surface
  std::vector<double> mass_, atol_scale_;
  Control control_;
  ModelEffects effects_;
  // The resistive reactant's rise over R_0 at a particle's mean stoichiometry (the knee profile
  // of cell/diffusivity_profile.hpp); null while the reactant is off.
  ScalarFunctionPtr reactant_factor_;
  bool film_frozen_ = false;
};

}  // namespace bms
