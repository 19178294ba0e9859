#pragma once
// Doyle-Fuller-Newman pseudo-2D cell model with the Ramadass side reaction (paper eqs 1-12),
// discretised by finite volumes in x (electrolyte, electrodes) and r (every particle).
// The DAE is written as  F(t, y, y') = M y' - g(y, t) = 0  with M diagonal (zero on the
// algebraic rows). g is templated on the scalar type so its Jacobian is exact (dual numbers).
#include <cmath>
#include <vector>

#include "bms/fw/dual.hpp"
#include "bms/fw/physical_constants.hpp"
#include "cell/cell_parameters.hpp"

namespace bms {

inline constexpr double kFaraday_c_mol = fw::kFaradayC_mol;
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

// Effects the plain DFN lacks, switchable in the truth model (issue 7 adds the rest).
struct ModelEffects {
  double contact_resistance_ohm = 0.0;
};

class DfnModel {
 public:
  DfnModel(const CellParameters& cell, const DfnMesh& mesh, double temperature_k);

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
  bool is_differential(int i) const { return mass_[i] != 0.0; }
  const std::vector<double>& mass() const { return mass_; }
  const std::vector<double>& abs_tolerance_scale() const { return atol_scale_; }

  void set_control(const Control& c) { control_ = c; }
  const Control& control() const { return control_; }
  ModelEffects& effects() { return effects_; }
  const ModelEffects& effects() const { return effects_; }
  bool side_reaction_enabled() const { return cell_.side.enabled; }
  void set_side_reaction_enabled(bool on) { cell_.side.enabled = on; }
  // When frozen, the film row becomes dR/dt = 0 (the film resistance is an input).
  void set_film_frozen(bool frozen) { film_frozen_ = frozen; }

  // Initial state at rest (algebraic part is a guess; the solver makes it consistent).
  std::vector<double> initial_state(double stoich_neg, double stoich_pos, double ce_mol_m3,
                                    double r_film_ohm_m2) const;

  template <typename T>
  void eval_g(double t, const T* y, T* g) const;

  double current_setpoint_a(double t) const;

  // Derived outputs of a state.
  double terminal_voltage_v(const double* y) const;
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
  double film_growth_factor() const;  // dR/dt = -factor * mean(j_s)

 private:
  template <typename T> T side_current(const T& phis, const T& phie, const T& j, const T& r) const;

  CellParameters cell_;
  DfnMesh mesh_;
  double temperature_k_;
  double f_rt_;
  int nx_, ne_, cs_end_, n_;
  std::vector<double> dx_, eps_, te_, a_;  // per x cell (a_ = 0 in separator)
  std::vector<double> shell_vol_, face_r2_;  // per electrode (2 x n_r, n_r + 1)
  std::vector<double> center_dist_;          // per electrode, n_r - 1 distances between shell centres
  std::vector<double> surface_half_;         // per electrode, centre of the last shell to the surface
  std::vector<double> mass_, atol_scale_;
  Control control_;
  ModelEffects effects_;
  bool film_frozen_ = false;
};

}  // namespace bms
