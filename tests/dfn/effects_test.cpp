// The truth model's switchable effects: OCV hysteresis and the lumped thermal model
// with Arrhenius properties. Coarse meshes and short protocols keep these fast.
#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "cell/paper_cell.hpp"
#include "dfn/dfn_solver.hpp"
#include "io/input_error.hpp"
#include "sim/cell_catalog.hpp"
#include "sim/cycler.hpp"

namespace bms {
namespace {

const DfnMesh kCoarse{8, 4, 8, 8};

SimulationConfig config_for(const CellParameters& cell, const ModelEffects& effects) {
  SimulationConfig cfg;
  cfg.cell = cell;
  cfg.mesh = kCoarse;
  cfg.temperature_k = cell.thermal.ambient_temperature_k;
  cfg.ic = default_initial_conditions(cell);
  cfg.effects = effects;
  return cfg;
}

// Piecewise-constant profile: (duration s, current A) segments, sampled every dt.
struct Profile {
  std::vector<double> t_s, current_a;
};
Profile segments(const std::vector<std::pair<double, double>>& segs, double dt) {
  Profile p;
  double t0 = 0.0;
  for (const auto& [duration, current] : segs) {
    for (double t = 0.0; t < duration - 1e-9; t += dt) {
      p.t_s.push_back(t0 + t);
      p.current_a.push_back(current);
    }
    t0 += duration;
  }
  p.t_s.push_back(t0);
  p.current_a.push_back(segs.back().second);
  return p;
}

SimulationResult run(const SimulationConfig& cfg, const Profile& p) {
  return run_current_profile(cfg, p.t_s, p.current_a, 1.0, 5.0);
}

TEST(EffectsOff, NoExtraStatesAndIdenticalResidual) {
  const CellParameters cell = make_paper_cell();
  DfnModel plain(cell, kCoarse, 298.15);
  ModelEffects off;
  off.hysteresis_rate_per_soc = 10.0;  // a rate without a gap changes nothing
  DfnModel same(cell, kCoarse, 298.15, off);
  ASSERT_EQ(plain.size(), same.size());
  EXPECT_LT(plain.idx_hysteresis(), 0);
  EXPECT_LT(plain.idx_temperature(), 0);
  const auto y = plain.initial_state(0.6, 0.4, 1000.0, 1e-3);
  std::vector<double> g1(plain.size()), g2(plain.size());
  plain.eval_g(0.0, y.data(), g1.data());
  same.eval_g(0.0, y.data(), g2.data());
  EXPECT_EQ(g1, g2);
  ModelEffects on;
  on.hysteresis_v = 0.01;
  on.thermal_h_w_per_k = 0.1;
  EXPECT_EQ(DfnModel(cell, kCoarse, 298.15, on).size(), plain.size() + 1 + plain.n_x() + 1);
}

TEST(Hysteresis, GapOfTwoHBetweenChargeAndDischargeAtLowCurrent) {
  CellParameters cell = make_paper_cell();
  cell.side.enabled = false;
  const double h_v = 0.01, current = cell.nominal_capacity_ah / 20.0;  // C/20
  const double leg_s = 0.2 * 20.0 * 3600.0;                           // 20 % SOC each way
  const auto p = segments({{leg_s, current}, {leg_s, -current}}, 60.0);
  ModelEffects hyst;
  hyst.hysteresis_v = h_v;
  hyst.hysteresis_initial_branch = -1.0;  // already on the discharge branch
  const auto with = run(config_for(cell, hyst), p);
  const auto without = run(config_for(cell, ModelEffects{}), p);
  ASSERT_EQ(with.samples.size(), p.t_s.size()) << with.note;
  ASSERT_EQ(without.samples.size(), p.t_s.size()) << without.note;
  // Same state of charge: 8 % SOC into the discharge, and 12 % SOC into the charge back.
  const auto at = [&](const SimulationResult& r, double t) {
    for (const auto& s : r.samples)
      if (std::abs(s.t_s - t) < 1e-6) return s;
    ADD_FAILURE() << "no sample at " << t;
    return r.samples.front();
  };
  const double t_dis = 0.4 * leg_s, t_chg = leg_s + 0.6 * leg_s;
  const double gap_with = at(with, t_chg).voltage_v - at(with, t_dis).voltage_v;
  const double gap_without = at(without, t_chg).voltage_v - at(without, t_dis).voltage_v;
  // 12 % SOC after the reversal the state has closed all but exp(-50 x 0.12) = 0.25 % of 2H.
  EXPECT_NEAR(gap_with - gap_without, 2.0 * h_v, 0.02 * 2.0 * h_v);
  EXPECT_NEAR(at(with, t_dis).hysteresis_v, -h_v, 1e-6);
  // Path dependence: h follows the charge moved, not the time. A tenth of the current for ten
  // times as long reaches the same h.
  ModelEffects from_charge = hyst;
  from_charge.hysteresis_initial_branch = 1.0;
  const double moved_s = 0.03 * 20.0 * 3600.0;  // 3 % SOC at C/20
  const auto fast = run(config_for(cell, from_charge), segments({{moved_s, current}}, 60.0));
  const auto slow = run(config_for(cell, from_charge), segments({{10.0 * moved_s, 0.1 * current}}, 600.0));
  const double h_fast = fast.samples.back().hysteresis_v, h_slow = slow.samples.back().hysteresis_v;
  EXPECT_NEAR(h_fast, h_v * (2.0 * std::exp(-50.0 * 0.03) - 1.0), 1e-5);
  EXPECT_NEAR(h_slow, h_fast, 1e-6);
}

TEST(Thermal, TwoCDischargeHeatsAndConservesEnergy) {
  const CellParameters cell = load_cell("aboutenergy");
  ModelEffects th;
  th.thermal_h_w_per_k = 0.05;
  const double current = 2.0 * cell.nominal_capacity_ah;
  const auto p = segments({{1500.0, current}}, 5.0);
  const auto r = run(config_for(cell, th), p);
  ASSERT_EQ(r.samples.size(), p.t_s.size()) << r.note;
  const double t_amb = cell.thermal.ambient_temperature_k;
  const double rise = r.samples.back().temperature_k - t_amb;
  // An 18650 heats by several K in a 2C discharge (models.md section 5).
  EXPECT_GT(rise, 3.0);
  EXPECT_LT(rise, 30.0);
  // Energy: heat generated = heat stored + heat lost to ambient (trapezoid on 5 s samples).
  DfnModel m(cell, kCoarse, t_amb, th);
  const double c_j_k = m.heat_capacity_j_k();
  double generated = 0.0, lost = 0.0;
  for (size_t i = 1; i < r.samples.size(); ++i) {
    const auto &a = r.samples[i - 1], &b = r.samples[i];
    const double dt = b.t_s - a.t_s;
    generated += 0.5 * dt * (a.heat_w + b.heat_w);
    lost += 0.5 * dt * th.thermal_h_w_per_k * (a.temperature_k + b.temperature_k - 2.0 * t_amb);
  }
  const double stored = c_j_k * rise;
  EXPECT_GT(generated, 0.0);
  EXPECT_NEAR(stored + lost, generated, 5e-4 * generated);
}

TEST(Thermal, LocalHeatSourcesAddUpToTheElectricalLoss) {
  const CellParameters cell = load_cell("aboutenergy");
  ModelEffects eff;
  eff.thermal_h_w_per_k = 0.05;
  eff.contact_resistance_ohm = 2e-3;
  eff.hysteresis_v = 0.01;
  eff.hysteresis_initial_branch = -1.0;  // on the discharge branch: -I h = I H
  DfnModel m(cell, kCoarse, cell.thermal.ambient_temperature_k, eff);
  DfnSolver solver(m, SolverSettings{});
  m.set_control({ControlKind::current, 0.0});
  const auto ic = default_initial_conditions(cell);
  solver.start(0.0, m.initial_state(ic.stoich_neg, ic.stoich_pos, ic.electrolyte_mol_m3, 0.0));
  solver.switch_control({ControlKind::current, 4.0}, StopConditions{});
  for (double t : {10.0, 300.0, 900.0}) {
    ASSERT_EQ(solver.advance_to(t), DfnSolver::Result::reached);
    const HeatRates h = m.heat_rates(solver.y().data());
    SCOPED_TRACE(t);
    EXPECT_GT(h.joule_w, 0.0);
    EXPECT_GT(h.reaction_w, 0.0);
    EXPECT_NEAR(h.hysteresis_w, 4.0 * eff.hysteresis_v, 1e-9);
    // Sum of the local terms = what the reactions deliver - what the terminals take.
    EXPECT_NEAR(h.joule_w + h.reaction_w + h.hysteresis_w, h.chemical_power_w - h.electrical_power_w,
                1e-5 * h.chemical_power_w);
  }
  // The entropic term of the whole cell is -I T d(Up - Un)/dT; here it only has to be finite
  // and far smaller than the chemical power.
  const HeatRates h = m.heat_rates(solver.y().data());
  EXPECT_LT(std::abs(h.reversible_w), 0.2 * h.chemical_power_w);
}

TEST(Thermal, AtTheReferenceTemperatureEqualsTheIsothermalModel) {
  const CellParameters cell = load_cell("aboutenergy");
  const auto p = segments({{600.0, 2.0}}, 10.0);
  const auto iso = run(config_for(cell, ModelEffects{}), p);
  ModelEffects clamped;
  clamped.thermal_h_w_per_k = 1e5;  // the cell cannot leave ambient = reference temperature
  const auto th = run(config_for(cell, clamped), p);
  ASSERT_EQ(iso.samples.size(), th.samples.size());
  double max_dv = 0.0, max_dt = 0.0;
  for (size_t i = 1; i < iso.samples.size(); ++i) {
    max_dv = std::max(max_dv, std::abs(iso.samples[i].voltage_v - th.samples[i].voltage_v));
    max_dt = std::max(max_dt, std::abs(th.samples[i].temperature_k - cell.thermal.reference_temperature_k));
  }
  EXPECT_LT(max_dt, 1e-3);
  EXPECT_LT(max_dv, 2e-5);
  // Away from the reference the Arrhenius factors act: 10 K warmer, less polarisation.
  SimulationConfig warm = config_for(cell, ModelEffects{});
  warm.temperature_k = cell.thermal.reference_temperature_k + 10.0;
  const auto w = run(warm, p);
  ASSERT_EQ(w.samples.size(), iso.samples.size());
  const double dv_mv = 1e3 * (w.samples[30].voltage_v - iso.samples[30].voltage_v);
  EXPECT_GT(dv_mv, 5.0);
  EXPECT_LT(dv_mv, 200.0);
}

TEST(EffectsInput, BadValuesAreInputErrors) {
  const CellParameters cell = make_paper_cell();
  ModelEffects e;
  e.hysteresis_v = -0.01;
  EXPECT_THROW(DfnModel(cell, kCoarse, 298.15, e), InputError);
  e = ModelEffects{};
  e.thermal_h_w_per_k = std::nan("");
  EXPECT_THROW(DfnModel(cell, kCoarse, 298.15, e), InputError);
  e = ModelEffects{};
  e.thermal_h_w_per_k = 0.1;
  CellParameters no_heat = cell;
  no_heat.thermal.specific_heat_j_kg_k = 0.0;
  EXPECT_THROW(DfnModel(no_heat, kCoarse, 298.15, e), InputError);
}

}  // namespace
}  // namespace bms
