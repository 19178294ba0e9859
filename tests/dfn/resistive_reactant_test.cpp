// The cathode's resistive reactant (ModelEffects::resistive_reactant_positive_*): off is the plain
// model bit for bit, a constant resistance is an ohmic drop of its share of the cell, a
// resistance that rises as the particles fill brings the knee of a discharge earlier and makes
// it gradual, and lithium is conserved.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "ae_discharge.hpp"
#include "dfn/dfn_solver.hpp"
#include "io/input_error.hpp"
#include "sim/cell_catalog.hpp"
#include "sim/cycler.hpp"

namespace bms {
namespace {

using ae_discharge::ae_cell;
using ae_discharge::Discharge;
using ae_discharge::kCoarse;

Discharge discharge(const CellParameters& cell, const ModelEffects& effects, double current_a) {
  return ae_discharge::discharge(cell, effects, current_a, 2.0);
}

// The cathode's particle surface in the cell (m2): a L A.
double cathode_surface_m2(const CellParameters& c) {
  return c.positive.surface_area_per_volume_m() * c.positive.thickness_m * c.electrode_area_m2;
}

TEST(ResistiveReactant, ZeroResistanceIsThePlainModelBitForBit) {
  const CellParameters cell = ae_cell();
  ModelEffects shaped;  // a rise and a knee without a resistance: off
  shaped.resistive_reactant_positive_log10 = 2.0;
  shaped.resistive_reactant_positive_knee = 0.6;
  const Discharge a = discharge(cell, {}, 2.0), b = discharge(cell, shaped, 2.0);
  EXPECT_EQ(a.end_s, b.end_s);
  ASSERT_EQ(a.v.size(), b.v.size());
  for (size_t k = 0; k < a.v.size(); ++k) ASSERT_EQ(a.v[k], b.v[k]) << "sample " << k;
}

// With no rise the drop is j R in every particle: the same current through the cathode's
// surface, so about I R / (a L A) at the terminals (the reaction spreads a little more evenly).
TEST(ResistiveReactant, ConstantResistanceIsAnOhmicDropOfItsShare) {
  const CellParameters cell = ae_cell();
  ModelEffects flat;
  flat.resistive_reactant_positive_ohm_m2 = 0.5;
  const Discharge plain = discharge(cell, {}, 2.0), rr = discharge(cell, flat, 2.0);
  const double expected_v = 2.0 * 0.5 / cathode_surface_m2(cell);
  ASSERT_GT(plain.v.size(), 20u);
  for (size_t k : {size_t{5}, plain.v.size() / 3, plain.v.size() / 2})
    EXPECT_NEAR(plain.v[k] - rr.v[k], expected_v, 0.15 * expected_v) << "sample " << k;
  EXPECT_GT(expected_v, 0.03);  // the check is not lost in the solver's tolerance
}

TEST(ResistiveReactant, RisingResistanceBringsTheKneeEarlierAndConservesLithium) {
  const CellParameters cell = ae_cell();
  ModelEffects low, rising;
  low.resistive_reactant_positive_ohm_m2 = rising.resistive_reactant_positive_ohm_m2 = 0.05;
  rising.resistive_reactant_positive_log10 = 2.5;  // 316 x at x = 1
  rising.resistive_reactant_positive_knee = 0.6;
  const Discharge flat = discharge(cell, low, 2.0), risen = discharge(cell, rising, 2.0);
  EXPECT_LT(risen.inventory_drift, 1e-6);
  // The knee (the fall through 3.0 V) comes earlier; the end at 2.0 V, set by the cathode's
  // potential cliff, hardly moves.
  const auto below_3v_s = [](const Discharge& d) {
    for (size_t k = 0; k < d.v.size(); ++k)
      if (d.v[k] < 3.0) return 60.0 * static_cast<double>(k + 1);
    return d.end_s;
  };
  EXPECT_LT(below_3v_s(risen), below_3v_s(flat) - 120.0) << below_3v_s(risen) << " vs " << below_3v_s(flat);
  // Below the knee (the first third of the discharge) nothing changes.
  EXPECT_NEAR(risen.v[risen.v.size() / 4], flat.v[risen.v.size() / 4], 1e-3);
  // The rise is gradual: ten minutes before its end the risen cell is already 20 mV below
  // the flat one, and still above 2.8 V.
  const size_t early = risen.v.size() - 11;
  EXPECT_LT(risen.v[early], flat.v[early] - 0.02);
  EXPECT_GT(risen.v[early], 2.8);
}

// A reactant of 0.05 ohm m2 below a knee at x = 0.6, rising 2.5 decades to x = 1.
ModelEffects knee_reactant() {
  ModelEffects e;
  e.resistive_reactant_positive_ohm_m2 = 0.05;
  e.resistive_reactant_positive_log10 = 2.5;
  e.resistive_reactant_positive_knee = 0.6;
  return e;
}

// The activation energy of the reactant's resistance (ModelEffects::resistive_reactant_positive_ea_j_mol).
// At the reference temperature without self-heating it changes nothing, bit for bit.
TEST(ResistiveReactant, ActivationEnergyAtTheReferenceTemperatureIsBitForBit) {
  const CellParameters cell = ae_cell();
  const ModelEffects base = knee_reactant();
  ModelEffects activated = knee_reactant();
  activated.resistive_reactant_positive_ea_j_mol = 40e3;
  ASSERT_EQ(cell.thermal.reference_temperature_k, 298.15);
  const Discharge a = discharge(cell, base, 2.0), b = discharge(cell, activated, 2.0);
  EXPECT_EQ(a.end_s, b.end_s);
  ASSERT_EQ(a.v.size(), b.v.size());
  for (size_t k = 0; k < a.v.size(); ++k) ASSERT_EQ(a.v[k], b.v[k]) << "sample " << k;
}

// Held 20 K above the reference, the resistance is R exp(Ea/Rgas (1/T - 1/T_ref)): the same
// discharge as Ea = 0 with R scaled by that factor by hand.
TEST(ResistiveReactant, ActivationEnergyScalesTheResistanceByArrhenius) {
  const CellParameters cell = ae_cell();
  const double t_k = 318.15, ea = 40e3;
  const double factor = std::exp(ea / 8.314462618 * (1.0 / t_k - 1.0 / 298.15));  // about 0.37
  ModelEffects activated, scaled, at_r;
  activated.resistive_reactant_positive_ohm_m2 = at_r.resistive_reactant_positive_ohm_m2 = 0.5;
  activated.resistive_reactant_positive_ea_j_mol = ea;
  scaled.resistive_reactant_positive_ohm_m2 = 0.5 * factor;
  const Discharge a = ae_discharge::discharge(cell, activated, 2.0, 2.0, t_k);
  const Discharge s = ae_discharge::discharge(cell, scaled, 2.0, 2.0, t_k);
  const Discharge unscaled = ae_discharge::discharge(cell, at_r, 2.0, 2.0, t_k);
  ASSERT_EQ(a.v.size(), s.v.size());
  for (size_t k = 0; k < a.v.size(); ++k) ASSERT_NEAR(a.v[k], s.v[k], 1e-6) << "sample " << k;
  // The scaling matters: the activated cell's drop is tens of mV smaller than at R itself.
  EXPECT_GT(a.v[5] - unscaled.v[5], 0.02);
}

// With self-heating the cell warms during a 2C discharge, so an activated reactant resists less
// and the voltage late in the discharge (where the cell is warmest and the resistance highest)
// is higher than with the temperature-independent resistance.
TEST(ResistiveReactant, ActivationEnergyWithSelfHeatingLowersTheDrop) {
  const CellParameters cell = ae_cell();
  ModelEffects plain_r = knee_reactant(), activated = knee_reactant();
  plain_r.thermal_h_w_per_k = activated.thermal_h_w_per_k = 0.05;
  activated.resistive_reactant_positive_ea_j_mol = 40e3;
  const Discharge p = discharge(cell, plain_r, 3.0), a = discharge(cell, activated, 3.0);
  ASSERT_GT(p.v.size(), 12u);
  ASSERT_GT(a.v.size(), 12u);
  // At the start the cell is at ambient: the same voltage within 1 mV.
  EXPECT_NEAR(a.v[0], p.v[0], 1e-3);
  // Ten minutes before the temperature-independent cell's end: at least 10 mV higher.
  const size_t late = p.v.size() - 11;
  EXPECT_GT(a.v[late], p.v[late] + 0.01) << a.v[late] << " vs " << p.v[late];
  EXPECT_GE(a.end_s, p.end_s);
}

TEST(ResistiveReactant, BadValuesAreInputErrors) {
  const CellParameters cell = ae_cell();
  ModelEffects eff;
  eff.resistive_reactant_positive_ohm_m2 = -0.1;
  EXPECT_THROW(DfnModel(cell, kCoarse, 298.15, eff), InputError);
  eff.resistive_reactant_positive_ohm_m2 = NAN;
  EXPECT_THROW(DfnModel(cell, kCoarse, 298.15, eff), InputError);
  eff.resistive_reactant_positive_ohm_m2 = 0.1;
  eff.resistive_reactant_positive_log10 = 7.0;
  EXPECT_THROW(DfnModel(cell, kCoarse, 298.15, eff), InputError);
  eff.resistive_reactant_positive_log10 = 2.0;
  eff.resistive_reactant_positive_knee = 1.0;
  EXPECT_THROW(DfnModel(cell, kCoarse, 298.15, eff), InputError);
  eff.resistive_reactant_positive_knee = 0.5;
  eff.resistive_reactant_positive_ea_j_mol = -1.0;
  EXPECT_THROW(DfnModel(cell, kCoarse, 298.15, eff), InputError);
  eff.resistive_reactant_positive_ea_j_mol = NAN;
  EXPECT_THROW(DfnModel(cell, kCoarse, 298.15, eff), InputError);
}

}  // namespace
}  // namespace bms
