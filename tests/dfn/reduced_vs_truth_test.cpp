// The firmware's reduced model against the truth DFN (paper cell), and the two
// parameter sets agreeing (one source of truth: bms/fw/model/paper_cell.hpp).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "bms/fw/model/reduced_cell.hpp"
#include "cell/paper_cell.hpp"
#include "estimation/estimate_run.hpp"
#include "sim/cycler.hpp"

namespace {

using bms::fw::Mode;

TEST(ReducedVsTruth, ParametersAgreeWithTheHostSet) {
  const bms::CellParameters host = bms::make_paper_cell();
  using T = bms::fw::PaperCellTraits;
  EXPECT_EQ(T::kAreaM2, host.electrode_area_m2);
  EXPECT_EQ(T::kNeg.thickness_m, host.negative.thickness_m);
  EXPECT_EQ(T::kPos.thickness_m, host.positive.thickness_m);
  EXPECT_EQ(T::kNeg.particle_radius_m, host.negative.particle_radius_m);
  EXPECT_EQ(T::kNeg.solid_diffusivity_m2_s, host.negative.solid_diffusivity_m2_s);
  EXPECT_EQ(T::kPos.i0_coefficient, host.positive.i0_coefficient);
  EXPECT_EQ(T::kSideExchangeAM2, host.side.exchange_current_a_m2);
  EXPECT_EQ(T::kSideRefPotentialV, host.side.reference_potential_v);
  EXPECT_EQ(T::kTransference, host.electrolyte.transference_number);
  for (double x : {0.05, 0.3, 0.6, 0.9}) {
    EXPECT_EQ(T::ocp_neg_v(x), host.negative.ocp_v->value(x));
    EXPECT_EQ(T::ocp_pos_v(x), host.positive.ocp_v->value(x));
  }
  for (double c : {500.0, 1266.9, 2000.0}) {
    EXPECT_EQ(T::electrolyte_conductivity_s_m(c), host.electrolyte.conductivity_s_m->value(c));
    EXPECT_EQ(T::electrolyte_diffusivity_m2_s(c), host.electrolyte.diffusivity_m2_s->value(c));
  }
}

struct ModeError {
  double sum2 = 0, max = 0;
  long n = 0;
  void add(double e) { sum2 += e * e; n += 1; max = std::max(max, std::abs(e)); }
  double rms() const { return n ? std::sqrt(sum2 / static_cast<double>(n)) : 0.0; }
};

// Drives the reduced model with the truth's current (CC, rest) or voltage (CV) and the
// truth's film resistance; voltage error in mV (current error in mA in CV).
TEST(ReducedVsTruth, FullCccvCycleVoltageError) {
  bms::SimulationConfig cfg;
  cfg.cell = bms::make_paper_cell();
  cfg.ic = bms::default_initial_conditions(cfg.cell);
  bms::CccvProtocol p;
  p.cycles = 1;
  const auto sim = bms::run_cccv(cfg, p);
  bms::fw::ReducedCell<double> m;
  m.init_default();
  ModeError err[5];
  for (std::size_t i = 1; i < sim.samples.size(); ++i) {
    const auto& s = sim.samples[i];
    const double dt = s.t_s - sim.samples[i - 1].t_s;
    const int mi = static_cast<int>(s.mode);
    if (s.mode == Mode::cv_charge || s.mode == Mode::cv_discharge) {
      const auto r = m.step_voltage(s.voltage_v, s.r_film_ohm_m2, dt);
      err[mi].add((r.current_a - s.current_a) * 1e3);
    } else {
      const auto r = m.step_current(s.current_a, s.r_film_ohm_m2, dt);
      err[mi].add((r.voltage_v - s.voltage_v) * 1e3);
    }
  }
  std::printf("reduced model: %d states (%d+%d shells, %d electrolyte cells, + Li lost, charge)\n",
              bms::fw::ReducedCell<double>::kNumStates, bms::fw::ReducedCell<double>::kNrN,
              bms::fw::ReducedCell<double>::kNrP, bms::fw::ReducedCell<double>::kNx);
  for (int mi : {1, 2, 3, 4})
    std::printf("  %-12s rms %.3f max %.3f %s over %ld ticks\n", bms::fw::mode_name(static_cast<Mode>(mi)),
                err[mi].rms(), err[mi].max, (mi == 2 || mi == 4) ? "mA" : "mV", err[mi].n);
  // Target: RMS <= 1 mV during CC charging (met). The max target (5 mV) is not met:
  // the first seconds after a deep discharge (docs/results/firmware-model.md); the bound
  // below only guards against regressions of the measured 17 mV.
  EXPECT_LE(err[3].rms(), 1.0);
  EXPECT_LE(err[3].max, 20.0);
  EXPECT_LE(err[1].rms(), 1.0);
}

// CC-charge voltage error [mV] of the reduced model driven by a truth's current, CV voltage and
// film, with the truth's temperature given to the model each tick (or never: isothermal at 298.15 K).
ModeError cc_charge_error(const bms::SimulationResult& sim, bool give_temperature) {
  bms::fw::ReducedCell<double> m;
  m.init_default();
  ModeError err;
  for (std::size_t i = 1; i < sim.samples.size(); ++i) {
    const auto& s = sim.samples[i];
    const double dt = s.t_s - sim.samples[i - 1].t_s;
    if (give_temperature) {
      EXPECT_TRUE(m.set_temperature_k(s.temperature_k));
    }
    if (s.mode == Mode::cv_charge || s.mode == Mode::cv_discharge) {
      m.step_voltage(s.voltage_v, s.r_film_ohm_m2, dt);
    } else {
      const auto r = m.step_current(s.current_a, s.r_film_ohm_m2, dt);
      if (s.mode == Mode::cc_charge) err.add((r.voltage_v - s.voltage_v) * 1e3);
    }
  }
  return err;
}

// The model follows the measured temperature: a truth at 5 C, and one that heats itself (lumped
// thermal model, 0.05 W/K: 298-302 K over a cycle), are tracked as the 25 C truth is (RMS
// <= 1 mV in CC charge; measured 0.35 / 0.28 mV); isothermal at 25 C the same model is further
// off (measured 5.3 mV, 15x / 0.81 mV, 2.9x).
TEST(ReducedVsTruth, TheModelFollowsTheTruthsTemperature) {
  bms::CccvProtocol p;
  p.cycles = 1;
  for (const bool self_heating : {false, true}) {
    bms::SimulationConfig cfg;
    cfg.cell = bms::make_paper_cell();
    cfg.ic = bms::default_initial_conditions(cfg.cell);
    if (self_heating) {
      cfg.effects.thermal_h_w_per_k = 0.05;
    } else {
      cfg.temperature_k = 278.15;
    }
    const auto sim = bms::run_cccv(cfg, p);
    const ModeError with = cc_charge_error(sim, true), without = cc_charge_error(sim, false);
    std::printf("%s: CC charge rms %.3f mV with the temperature, %.3f mV isothermal at 298.15 K\n",
                self_heating ? "self-heating" : "278.15 K", with.rms(), without.rms());
    EXPECT_LE(with.rms(), 1.0);
    EXPECT_GT(without.rms(), (self_heating ? 2.0 : 10.0) * with.rms());
  }
}

TEST(ReducedVsTruth, EstimatorRunsOverTwoCyclesWithinBounds) {
  bms::SimulationConfig cfg;
  cfg.cell = bms::make_paper_cell();
  cfg.ic = bms::default_initial_conditions(cfg.cell);
  bms::CccvProtocol p;
  p.cycles = 2;
  const auto sim = bms::run_cccv(cfg, p);
  bms::EstimateData d;
  for (const auto& s : sim.samples) {
    d.t_s.push_back(s.t_s);
    d.current_a.push_back(s.current_a);
    d.voltage_v.push_back(s.voltage_v);
    d.cycle.push_back(s.cycle);
    d.r_film_true_ohm_m2.push_back(s.r_film_ohm_m2);
    d.true_mode.push_back(s.mode);
  }
  bms::EstimateOptions o;
  o.profile = bms::fw::Profile::paper;  // the paper's RCSI
  o.ic = cfg.ic;
  const auto r = bms::run_estimate(d, cfg.cell, o);
  ASSERT_EQ(r.cycles.size(), 2u);
  for (const auto& row : r.rows) {
    ASSERT_TRUE(std::isfinite(row.r_film_est_ohm_m2));
    if (row.rcsi_active) {
      ASSERT_EQ(row.mode, Mode::cc_charge);
    }
  }
  for (const auto& c : r.cycles) {
    std::printf("cycle %d: median error %.2f %%, end %.2f %%\n", c.cycle, c.r_film_err_median_pct,
                c.r_film_err_end_pct);
    EXPECT_GT(c.cc_charge_ticks, 17000u);
    // Regression guard at the measured level (about 11-15 % with the paper's settings), not
    // the 1 % target, which is not met (see docs/results/firmware-model.md).
    EXPECT_LT(c.r_film_err_median_pct, 25.0);
  }
  EXPECT_EQ(r.newton_cap_hits, 0u);
}

}  // namespace
