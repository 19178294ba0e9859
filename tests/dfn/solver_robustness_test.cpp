// The truth's solver through the cells that blind-identification studies draw: extra cyclable
// lithium leaves the anode nearly full at the end of the CV charge, and the 2.5 A discharge
// that follows must still start (consistent initialisation by continuation in the setpoint);
// more lithium than the anode holds at 3.6 V must end the run with a message naming the time,
// the phase and the electrode whose surface reached which limit.
#include <gtest/gtest.h>

#include <string>

#include "cell/paper_cell.hpp"
#include "io/input_error.hpp"
#include "sim/cycler.hpp"

namespace bms {
namespace {

// The paper cell at rest with `inventory_scale` times its cyclable lithium at the same
// open-circuit voltage: the initial stoichiometries `simulate --set inventory_scale=...`
// computes (sim/truth_parameters.cpp, scale_initial_inventory), fixed here.
SimulationConfig paper_with_inventory(double stoich_neg, double stoich_pos) {
  SimulationConfig cfg;
  cfg.cell = make_paper_cell();
  cfg.cell.negative.stoich_init = stoich_neg;
  cfg.cell.positive.stoich_init = stoich_pos;
  cfg.temperature_k = cfg.cell.thermal.ambient_temperature_k;
  cfg.ic = default_initial_conditions(cfg.cell);
  return cfg;
}

CccvProtocol paper_protocol(const CellParameters& cell, int cycles) {
  CccvProtocol p;
  p.cycles = cycles;
  p.v_min = cell.lower_voltage_v;
  p.v_max = cell.upper_voltage_v;
  return p;
}

TEST(SolverRobustness, DischargeStartsAfterChargingExtraLithium) {
  // inventory_scale 1.005 and 1.01: IDACalcIC from the CV charge's state failed at the start
  // of cycle 2 (t = 7348.42 s and 7404.87 s; anode surface 0.9965-0.9998).
  struct Case {
    double stoich_neg, stoich_pos, t_switch_s;
  };
  for (const Case c : {Case{0.84578458866548134, 0.1592152271091701, 7348.42},
                       Case{0.85076910029535258, 0.15923053127213119, 7404.87}}) {
    SCOPED_TRACE(c.stoich_neg);
    const auto cfg = paper_with_inventory(c.stoich_neg, c.stoich_pos);
    const auto res = run_cccv(cfg, paper_protocol(cfg.cell, 2));
    ASSERT_EQ(res.phases.size(), 8u);
    const PhaseMark& discharge2 = res.phases[4];
    EXPECT_EQ(discharge2.mode, Mode::cc_discharge);
    EXPECT_NEAR(discharge2.t_start_s, c.t_switch_s, 0.05);
    // The discharge leaves from a plausible state: 2.5 A at once, no spike in the voltage
    // (it rises by 25 mV over 2 s at 1.01 as the anode's surface leaves 0.9998 and its
    // exchange current grows).
    const SampleRecord* first = nullptr;
    const SampleRecord* later = nullptr;
    // Charge (discharge positive, A h) at the end of cycle 1's discharge, of cycle 1 and of
    // cycle 2's discharge.
    double q_discharged_1 = 0.0, q_end_1 = 0.0, q_discharged_2 = 0.0;
    for (const auto& s : res.samples) {
      const bool discharging = s.mode == Mode::cc_discharge || s.mode == Mode::cv_discharge;
      if (s.cycle == 1 && discharging) q_discharged_1 = s.charge_ah;
      if (s.cycle == 1) q_end_1 = s.charge_ah;
      if (s.cycle == 2 && discharging) q_discharged_2 = s.charge_ah;
      if (s.cycle != 2 || s.mode != Mode::cc_discharge) continue;
      if (!first) first = &s;
      if (!later && s.t_s >= first->t_s + 2.0) later = &s;
    }
    ASSERT_TRUE(first && later);
    EXPECT_DOUBLE_EQ(first->current_a, 2.5);
    EXPECT_GT(first->voltage_v, 3.2);
    EXPECT_LT(first->voltage_v, 3.5);
    EXPECT_NEAR(later->voltage_v, first->voltage_v, 0.05);
    // Cycle 2 gives back what cycle 1 charged, less the little lithium the film took.
    const double charged_1 = q_discharged_1 - q_end_1, discharged_2 = q_discharged_2 - q_end_1;
    EXPECT_GT(charged_1, 2.0);
    EXPECT_NEAR(discharged_2 / charged_1, 1.0, 0.01);
  }
}

TEST(SolverRobustness, TooMuchLithiumFillsTheAnodeAndEndsTheRun) {
  // inventory_scale 1.03: the CV charge at 3.6 V drives the anode's surface to 0.9999 while
  // the current is still above the CV end current; the run must stop there, saying so.
  const auto cfg = paper_with_inventory(0.87070700904675036, 0.15929188572457775);
  try {
    run_cccv(cfg, paper_protocol(cfg.cell, 1));
    FAIL() << "expected a RuntimeFailure";
  } catch (const RuntimeFailure& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("cycle 1, cv_charge"), std::string::npos) << what;
    EXPECT_NE(what.find("t = 7336."), std::string::npos) << what;
    EXPECT_NE(what.find("negative electrode's particle surface reached stoichiometry 0.9999"), std::string::npos)
        << what;
    EXPECT_NE(what.find("(limit 1,"), std::string::npos) << what;
    EXPECT_NE(what.find("is full"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace bms
