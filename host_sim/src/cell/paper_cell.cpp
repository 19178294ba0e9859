#include "cell/paper_cell.hpp"

#include <cmath>

#include "bms/fw/model/paper_cell.hpp"
#include "cell/template_function.hpp"

namespace bms {
namespace {


ElectrodeParameters electrode_from(const fw::paper::Electrode& e) {
  ElectrodeParameters p;
  p.thickness_m = e.thickness_m;
  p.particle_radius_m = e.particle_radius_m;
  p.solid_fraction = e.solid_fraction;
  p.porosity = e.porosity;
  p.transport_efficiency = std::pow(e.porosity, fw::paper::kBruggeman);
  p.solid_diffusivity_m2_s = e.solid_diffusivity_m2_s;
  p.max_concentration_mol_m3 = e.max_concentration_mol_m3;
  p.conductivity_eff_s_m = e.conductivity_eff_s_m;
  p.i0_coefficient = e.i0_coefficient;
  p.stoich_init = e.stoich_init;
  return p;
}

}  // namespace

CellParameters make_paper_cell() {
  namespace pc = fw::paper;
  CellParameters c;
  c.name = "paper";
  c.source = "built-in (firmware/include/bms/fw/model/paper_cell.hpp)";
  c.electrode_area_m2 = pc::kElectrodeArea_m2;
  c.lower_voltage_v = pc::kLowerVoltage_v;
  c.upper_voltage_v = pc::kUpperVoltage_v;
  c.nominal_capacity_ah = pc::kNominalCapacity_ah;
  c.initial_electrolyte_mol_m3 = pc::kElectrolyteInit_mol_m3;

  c.negative = electrode_from(pc::kNegative);
  c.negative.ocp_v = make_template_function([](auto x) { return pc::ocp_negative_v(x); });
  c.positive = electrode_from(pc::kPositive);
  c.positive.ocp_v = make_template_function([](auto x) { return pc::ocp_positive_v(x); });
  // Stoichiometry window used only to report state of charge: the cell's voltage limits
  // at rest bracket these (the paper gives no window).
  c.negative.stoich_min = 0.0;
  c.negative.stoich_max = 1.0;
  c.positive.stoich_min = 0.0;
  c.positive.stoich_max = 1.0;

  c.separator.thickness_m = pc::kSeparatorThickness_m;
  c.separator.porosity = pc::kSeparatorPorosity;
  c.separator.transport_efficiency = std::pow(pc::kSeparatorPorosity, pc::kBruggeman);

  c.electrolyte.initial_concentration_mol_m3 = pc::kElectrolyteInit_mol_m3;
  c.electrolyte.transference_number = pc::kTransference;
  c.electrolyte.diffusivity_m2_s =
      make_template_function([](auto x) { return pc::electrolyte_diffusivity_m2_s(x); });
  c.electrolyte.conductivity_s_m =
      make_template_function([](auto x) { return pc::electrolyte_conductivity_s_m(x); });

  c.side.enabled = true;
  c.side.reference_potential_v = pc::kSideRefPotential_v;
  c.side.exchange_current_a_m2 = pc::kSideExchange_a_m2;
  c.side.transfer_coefficient = pc::kSideAlpha;
  c.side.molar_mass_kg_mol = pc::kFilmMolarMass_kg_mol;
  c.side.density_kg_m3 = pc::kFilmDensity_kg_m3;
  c.side.film_conductivity_s_m = pc::kFilmConductivity_s_m;
  c.side.initial_film_resistance_ohm_m2 = pc::kInitialFilm_ohm_m2;

  c.thermal.ambient_temperature_k = pc::kTemperature_k;
  c.thermal.initial_temperature_k = pc::kTemperature_k;
  c.thermal.reference_temperature_k = pc::kTemperature_k;
  // Forman et al. give no thermal data. For the thermal effect: an A123 26650 cell, 76 g
  // (datasheet mass) in 26 mm x 65 mm (3.45e-5 m3), with 1100 J/(kg K), a typical lumped
  // heat capacity of LFP cells: about 84 J/K. No activation energies or entropic data: the
  // paper cell's properties do not depend on temperature (docs/results/measured-effects.md).
  c.thermal.volume_m3 = 3.45e-5;
  c.thermal.density_kg_m3 = 0.076 / 3.45e-5;
  c.thermal.specific_heat_j_kg_k = 1100.0;
  c.thermal.external_area_m2 = 2.0 * 3.14159265 * 0.013 * 0.065 + 2.0 * 3.14159265 * 0.013 * 0.013;
  return c;
}

}  // namespace bms
