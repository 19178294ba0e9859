#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "estimation/charges.hpp"
#include "sim/cell_catalog.hpp"

namespace {

// A discharge to the lower limit, a rest, a CC charge, a rest and a discharge step logged every
// 30 s, the step's first sample `first_tau_s` after the step began. Under the discharge the
// voltage falls as V_rest - I (R0 + b sqrt(tau)): an ohmic-plus-kinetic step and a diffusion
// polarisation growing with the square root of the time since the step.
struct Record {
  bms::EstimateData data;
  std::vector<bms::EstimateRow> rows;
};

constexpr double kR0Ohm = 0.1, kSqrtSlopeOhmPerSqrtS = 0.004, kDischargeA = 1.1, kRestV = 4.19;

void add(Record& r, double t_s, double i_a, double v_v, double step_time_s, bms::fw::Mode mode) {
  r.data.t_s.push_back(t_s);
  r.data.current_a.push_back(i_a);
  r.data.voltage_v.push_back(v_v);
  r.data.cycle.push_back(1);
  r.data.step_time_s.push_back(step_time_s);
  bms::EstimateRow row{};
  row.t_s = t_s;
  row.cycle = 1;
  row.mode = mode;
  row.r_film_est_ohm_m2 = 0.01;
  row.capacity_est_ah = std::nan("");
  r.rows.push_back(row);
}

Record record(double lower_v, double first_tau_s, bool step_time_logged) {
  using bms::fw::Mode;
  Record r;
  double t = 0.0;
  for (int k = 0; k < 4; ++k, t += 30.0) add(r, t, kDischargeA, lower_v + 0.01 * (3 - k), 30.0 * k, Mode::cc_discharge);
  for (int k = 0; k < 4; ++k, t += 30.0) add(r, t, 0.0, lower_v + 0.3, 30.0 * k, Mode::rest);
  for (int k = 0; k < 20; ++k, t += 30.0) add(r, t, -0.55, 3.9 + 0.01 * k, 30.0 * k, Mode::cc_charge);
  for (int k = 0; k < 4; ++k, t += 30.0) add(r, t, 0.0, kRestV, 30.0 * k, Mode::rest);
  const double step_start_s = t - 30.0 + (30.0 - first_tau_s);
  for (int k = 0; k < 4; ++k) {
    const double tau = first_tau_s + 30.0 * k;
    const double v = kRestV - kDischargeA * (kR0Ohm + kSqrtSlopeOhmPerSqrtS * std::sqrt(tau));
    add(r, step_start_s + tau, kDischargeA, v, tau, Mode::cc_discharge);
  }
  if (!step_time_logged) r.data.step_time_s.clear();
  return r;
}

TEST(Charges, DischargeOnsetResistanceIsTheStepsInstantWhateverTheLoggingDelay) {
  const bms::CellParameters cell = bms::load_cell("lco");
  for (double first_tau_s : {2.0, 9.0, 30.0}) {
    const Record r = record(cell.lower_voltage_v, first_tau_s, true);
    const auto charges = bms::find_charges(r.rows, r.data, cell, false);
    ASSERT_EQ(charges.size(), 1u) << first_tau_s;
    const bms::ChargeReport& c = charges.front();
    EXPECT_TRUE(c.counted_complete);
    // The first sample's drop carries the diffusion of its delay; the onset value does not.
    EXPECT_NEAR(c.r_discharge_step_ohm, kR0Ohm + kSqrtSlopeOhmPerSqrtS * std::sqrt(first_tau_s), 1e-9);
    EXPECT_NEAR(c.r_discharge_onset_ohm, kR0Ohm, 1e-9) << first_tau_s;
  }
}

TEST(Charges, DischargeOnsetIsUnknownWithoutTheCyclersStepTime) {
  const bms::CellParameters cell = bms::load_cell("lco");
  const Record r = record(cell.lower_voltage_v, 12.0, false);
  const auto charges = bms::find_charges(r.rows, r.data, cell, false);
  ASSERT_EQ(charges.size(), 1u);
  EXPECT_TRUE(std::isfinite(charges.front().r_discharge_step_ohm));
  EXPECT_TRUE(std::isnan(charges.front().r_discharge_onset_ohm));
}

}  // namespace
