#pragma once
// Parameters of a DFN cell (+ optional Ramadass side reaction), in SI units.
// Filled by the built-in `paper` set (paper_cell.cpp) or by the BPX reader (io/bpx_reader.cpp).
#include <string>

#include "cell/scalar_function.hpp"

namespace bms {

struct ElectrodeParameters {
  double thickness_m = 0.0;
  double particle_radius_m = 0.0;
  double solid_fraction = 0.0;          // active-material volume fraction eps_s
  double porosity = 0.0;                // electrolyte volume fraction eps_e
  double transport_efficiency = 0.0;    // eps_e^b: multiplies D_e and kappa
  double solid_diffusivity_m2_s = 0.0;  // at the reference temperature
  // D(x) = solid_diffusivity_m2_s * solid_diffusivity_factor(x), x = c_s / c_max the local
  // stoichiometry (a BPX expression in x relative to its value at x = 0.5, and/or a knee
  // profile: cell/diffusivity_profile.hpp). Null = constant D, the plain model.
  ScalarFunctionPtr solid_diffusivity_factor;
  double max_concentration_mol_m3 = 0.0;
  double conductivity_eff_s_m = 0.0;    // effective solid conductivity (already corrected)
  // Exchange current density i0 = i0_coefficient * sqrt(c_e * c_s * (c_max - c_s)) [A/m2],
  // i.e. i0_coefficient = F k for the paper's eq. 4 with alpha = 0.5, and
  // F k_norm / (sqrt(c_e0) c_max) for BPX's normalised rate constant.
  double i0_coefficient = 0.0;
  double stoich_min = 0.0;  // stoichiometry at 0 % state of charge (BPX)
  double stoich_max = 1.0;  // stoichiometry at 100 % state of charge (BPX)
  double stoich_init = 0.5;  // initial stoichiometry used by the simulator
  double diffusivity_activation_j_mol = 0.0;
  double rate_activation_j_mol = 0.0;
  ScalarFunctionPtr ocp_v;                 // open-circuit potential vs stoichiometry
  ScalarFunctionPtr entropic_v_k;          // dU/dT vs stoichiometry (may be null)

  double surface_area_per_volume_m() const { return 3.0 * solid_fraction / particle_radius_m; }
};

struct SeparatorParameters {
  double thickness_m = 0.0;
  double porosity = 0.0;
  double transport_efficiency = 0.0;
};

struct ElectrolyteParameters {
  double initial_concentration_mol_m3 = 1000.0;
  double transference_number = 0.0;
  ScalarFunctionPtr diffusivity_m2_s;     // D_e(c_e)
  ScalarFunctionPtr conductivity_s_m;     // kappa(c_e)
  // Thermodynamic factor 1 + dln f/dln c_e (c_e); null = 1 (ideal solution, the paper's model).
  ScalarFunctionPtr thermodynamic_factor;
  double diffusivity_activation_j_mol = 0.0;
  double conductivity_activation_j_mol = 0.0;
};

// Ramadass et al. side reaction in the negative electrode (paper eqs 9-12). The defaults are the
// paper's printed values (firmware/include/bms/fw/model/paper_cell.hpp; a test holds them together):
// a BPX file without side-reaction keys gets these (io/bpx_reader.cpp, docs/parameters.md).
struct SideReactionParameters {
  bool enabled = false;
  std::string source = "the paper's values";  // or the BPX file's keys
  double reference_potential_v = 0.4;         // U_sd,ref
  double exchange_current_a_m2 = 4e-9;        // i_0s
  double transfer_coefficient = 0.5;          // alpha
  double molar_mass_kg_mol = 7.3e4;           // M_p (as the paper prints it; see docs)
  double density_kg_m3 = 2.1e3;               // rho_p
  double film_conductivity_s_m = 1.0;         // K_p
  double initial_film_resistance_ohm_m2 = 3.391e-3;  // R_SEI
  // Factor on the film-growth law dR_film/dt alone (1 = the paper's; `--set film_growth_scale`):
  // it changes the film's resistance per mole of side product, not the lithium the side
  // reaction consumes, so the lithium loss derived from the film stays the same.
  double film_growth_scale = 1.0;
};

struct ThermalParameters {
  double ambient_temperature_k = 298.15;
  double initial_temperature_k = 298.15;
  double reference_temperature_k = 298.15;
  double specific_heat_j_kg_k = 0.0;
  double density_kg_m3 = 0.0;
  double volume_m3 = 0.0;
  double external_area_m2 = 0.0;
};

// Effects of the cell itself beyond the plain DFN, read from a BPX file's "User-defined" keys
// (io/bpx_reader.cpp, docs/parameters.md; `bmssim diagnose --write-cell` writes them). The truth
// model adds them to the effects a run switches on (DfnModel): the contact resistance adds, the
// others apply unless the run sets its own. Zero = off: the plain DFN.
struct CellEffectParameters {
  double contact_resistance_ohm = 0.0;   // "Contact resistance [Ohm]" (PyBaMM's name)
  double hysteresis_v = 0.0;             // "OCP hysteresis half-gap [V]"
  double hysteresis_rate_per_soc = 0.0;  // "OCP hysteresis rate per state of charge [-]"; 0 = the model's
  double thermal_h_w_per_k = 0.0;        // "Lumped heat transfer coefficient [W.K-1]"
  double particle_size_sigma = 0.0;      // "Positive particle-size log-normal standard deviation [-]"
  // The cathode's knee diffusivity profile (cell/diffusivity_profile.hpp):
  double diffusivity_profile_positive = 0.0;       // "Positive diffusivity profile log10 factor at full lithiation [-]"
  double diffusivity_profile_positive_knee = 0.5;  // "Positive diffusivity profile knee stoichiometry [-]"
  // The cathode's resistive reactant (ModelEffects, dfn/dfn_model.hpp):
  double resistive_reactant_positive_ohm_m2 = 0.0;  // "Positive resistive reactant resistance [Ohm.m2]"
  double resistive_reactant_positive_log10 = 0.0;   // "Positive resistive reactant log10 rise at full lithiation [-]"
  double resistive_reactant_positive_knee = 0.5;    // "Positive resistive reactant knee stoichiometry [-]"
  bool any() const {
    return contact_resistance_ohm > 0.0 || hysteresis_v > 0.0 || thermal_h_w_per_k > 0.0 || particle_size_sigma > 0.0 ||
           diffusivity_profile_positive != 0.0 || resistive_reactant_positive_ohm_m2 > 0.0;
  }
};

struct CellParameters {
  std::string name;
  std::string source;  // file or "built-in"
  double electrode_area_m2 = 0.0;
  double lower_voltage_v = 0.0;
  double upper_voltage_v = 0.0;
  double nominal_capacity_ah = 0.0;
  double initial_electrolyte_mol_m3 = 1000.0;
  ElectrodeParameters negative;
  SeparatorParameters separator;
  ElectrodeParameters positive;
  ElectrolyteParameters electrolyte;
  SideReactionParameters side;
  ThermalParameters thermal;
  CellEffectParameters effects;
};

}  // namespace bms
