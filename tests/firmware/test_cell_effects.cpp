// Cell and sensor effects around the firmware model (bms/fw/model/cell_effects.hpp): each effect's
// sign and size against the plain model, zero parameters reproduce the plain model bit for
// bit, CV ticks hit the voltage with the effects in, state images round-trip.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>

#include "bms/fw/estimation/bms_core.hpp"
#include "bms/fw/model/cell_effects.hpp"
#include "bms/fw/model/reduced_cell.hpp"

namespace {

using Plain = bms::fw::ReducedCell<double>;
using All = bms::fw::EffectsModel<Plain, bms::fw::kAllCellEffects>;
using bms::fw::EffectParameters;

constexpr double kFilm = bms::fw::paper::kInitialFilm_ohm_m2;
constexpr double kDt = 0.2;
constexpr double kQnom = 2.3;

EffectParameters<double> params() {
  EffectParameters<double> p;
  p.nominal_capacity_ah = kQnom;
  return p;
}

bool same_state(const Plain& a, const Plain& b) {
  return std::memcmp(&a.state(), &b.state(), sizeof(Plain::State)) == 0;
}

TEST(CellEffects, ZeroParametersReproduceThePlainModelBitForBit) {
  Plain plain, inner;
  plain.init_default();
  inner.init_default();
  All wrapped(inner, params());
  // CC discharge, CV discharge, rest, CC charge, CV charge: every path of the wrapper.
  auto both_current = [&](double i, int n) {
    for (int k = 0; k < n; ++k) {
      const auto a = plain.step_current(i, kFilm, kDt);
      const auto b = wrapped.step_current(i, kFilm, kDt);
      ASSERT_EQ(std::memcmp(&a.voltage_v, &b.voltage_v, sizeof(double)), 0);
      ASSERT_EQ(std::memcmp(&a.current_a, &b.current_a, sizeof(double)), 0);
    }
  };
  auto both_voltage = [&](double v, int n) {
    for (int k = 0; k < n; ++k) {
      const auto a = plain.step_voltage(v, kFilm, kDt);
      const auto b = wrapped.step_voltage(v, kFilm, kDt);
      ASSERT_EQ(std::memcmp(&a.voltage_v, &b.voltage_v, sizeof(double)), 0);
      ASSERT_EQ(std::memcmp(&a.current_a, &b.current_a, sizeof(double)), 0);
      ASSERT_EQ(a.newton_iterations, b.newton_iterations);
    }
  };
  both_current(2.5, 300);
  const double v_cv = plain.peek_voltage(2.4, kFilm, kDt);
  both_voltage(v_cv, 50);
  both_current(0.0, 50);
  both_current(-2.5, 300);
  both_voltage(plain.peek_voltage(-2.4, kFilm, kDt), 50);
  EXPECT_TRUE(same_state(plain, inner));
  EXPECT_EQ(wrapped.hysteresis_v(), 0.0);
}

TEST(CellEffects, ContactResistanceLowersDischargeAndRaisesChargeVoltageByRcTimesI) {
  Plain plain, inner;
  plain.init_default();
  inner.init_default();
  auto p = params();
  p.contact_resistance_ohm = 1e-3;
  bms::fw::EffectsModel<Plain, bms::fw::kEffectContactResistance> wrapped(inner, p);
  for (double i : {2.5, -2.5}) {
    for (int k = 0; k < 100; ++k) {
      const auto a = plain.step_current(i, kFilm, kDt);
      const auto b = wrapped.step_current(i, kFilm, kDt);
      EXPECT_NEAR(b.voltage_v - a.voltage_v, -1e-3 * i, 1e-14);
      EXPECT_EQ(b.current_a, i);
    }
  }
  EXPECT_TRUE(same_state(plain, inner));  // the resistance is outside the cell's chemistry
}

TEST(CellEffects, CurrentOffsetIsRemovedBeforeTheModelSeesTheCurrent) {
  // A sensor reading 10 mA high: the model must see the cell's current, and its reported
  // current is what the sensor would read.
  Plain plain, inner;
  plain.init_default();
  inner.init_default();
  auto p = params();
  p.current_offset_a = 0.01;
  bms::fw::EffectsModel<Plain, bms::fw::kEffectCurrentOffset> wrapped(inner, p);
  for (int k = 0; k < 500; ++k) {
    const auto a = plain.step_current(-2.5, kFilm, kDt);
    const auto b = wrapped.step_current(-2.5 + 0.01, kFilm, kDt);
    EXPECT_NEAR(b.voltage_v, a.voltage_v, 1e-12);
    EXPECT_NEAR(b.current_a, -2.49, 1e-12);
  }
  // Charge passed differs by exactly the offset's share: the model charged 2.5 A, not 2.49 A.
  EXPECT_NEAR(inner.state().charge_c, plain.state().charge_c, 1e-9);
  EXPECT_NEAR(inner.state().charge_c, -2.5 * kDt * 500, 1e-6);
}

TEST(CellEffects, CurrentGainDividesTheMeasuredCurrent) {
  Plain plain, inner;
  plain.init_default();
  inner.init_default();
  auto p = params();
  p.current_gain = 0.01;
  bms::fw::EffectsModel<Plain, bms::fw::kEffectCurrentGain> wrapped(inner, p);
  const auto a = plain.step_current(2.0, kFilm, kDt);
  const auto b = wrapped.step_current(2.0 * 1.01, kFilm, kDt);
  EXPECT_NEAR(b.voltage_v, a.voltage_v, 1e-12);
  EXPECT_NEAR(b.current_a, 2.02, 1e-12);
}

// The film's sd terms (temperature sensor, stated spread) need the inner model's probes: the
// wrapper must pass them on, seen through its effects, or an augmented cell loses them.
TEST(CellEffects, TemperatureProbeAndStatedSpreadReachTheInnerModel) {
  static_assert(bms::fw::kProbesTemperature<All, double>);
  static_assert(bms::fw::kGivesSpread<All, double>);
  Plain plain, inner;
  plain.init_default();
  inner.init_default();
  auto p = params();
  p.contact_resistance_ohm = 1e-3;
  p.current_gain = 0.01;
  bms::fw::EffectsModel<Plain, bms::fw::kEffectContactResistance | bms::fw::kEffectCurrentGain> wrapped(inner, p);
  bms::fw::StatedSpread<double> spread;
  spread.anode_i0_rel = 0.2;
  spread.area_rel = 0.03;
  for (int k = 0; k < 200; ++k) {
    const auto a = plain.step_current(-2.5, kFilm, kDt);
    const auto b = wrapped.step_current(-2.5 * 1.01, kFilm, kDt);
    const double dv_plain = plain.temperature_probe_voltage(-2.5, kFilm, kDt, 1.0) -
                            plain.temperature_probe_voltage(-2.5, kFilm, kDt, 0.0);
    const double dv_wrapped = wrapped.temperature_probe_voltage(-2.5 * 1.01, kFilm, kDt, 1.0) -
                              wrapped.temperature_probe_voltage(-2.5 * 1.01, kFilm, kDt, 0.0);
    ASSERT_NEAR(dv_wrapped, dv_plain, 1e-12);
    ASSERT_GT(std::fabs(dv_plain), 1e-6);
    const double sd_plain = plain.spread_voltage_sd_v(-2.5, a.voltage_v, spread);
    ASSERT_GT(sd_plain, 0.0);
    ASSERT_NEAR(wrapped.spread_voltage_sd_v(b.current_a, b.voltage_v, spread), sd_plain, 1e-12);
  }
}

TEST(CellEffects, HysteresisFollowsTheChargeMovedAsTheTruthModel) {
  // Truth (host_sim/src/dfn): dh/dt = -(kappa/(3600 Q)) (H I + |I| h), h(0) = +H. After a
  // discharge of 3 % of Q with kappa = 50: h = H (2 e^-1.5 - 1), whatever the current.
  const double hyst = 0.015;
  for (double current : {2.3, 0.23}) {
    Plain plain, inner;
    plain.init_default();
    inner.init_default();
    auto p = params();
    p.hysteresis_v = hyst;
    bms::fw::EffectsModel<Plain, bms::fw::kEffectHysteresis> wrapped(inner, p);
    EXPECT_DOUBLE_EQ(wrapped.hysteresis_v(), hyst);
    const int ticks = static_cast<int>(std::lround(0.03 * kQnom * 3600.0 / current / kDt));
    for (int k = 0; k < ticks; ++k) {
      const auto a = plain.step_current(current, kFilm, kDt);
      const auto b = wrapped.step_current(current, kFilm, kDt);
      EXPECT_NEAR(b.voltage_v - a.voltage_v, wrapped.hysteresis_v(), 1e-14);
    }
    EXPECT_NEAR(wrapped.hysteresis_v(), hyst * (2.0 * std::exp(-1.5) - 1.0), 1e-12) << current;
    // At rest h stays where it is.
    const double h = wrapped.hysteresis_v();
    for (int k = 0; k < 100; ++k) wrapped.step_current(0.0, kFilm, kDt);
    EXPECT_EQ(wrapped.hysteresis_v(), h);
    // A charge of 10 % of Q moves h towards the charge branch, +H.
    for (int k = 0; k < 1800; ++k) wrapped.step_current(-2.3, kFilm, kDt);
    EXPECT_NEAR(wrapped.hysteresis_v(), hyst + (h - hyst) * std::exp(-5.0), 1e-12);
  }
}

TEST(CellEffects, VoltageDrivenTickHitsTheTerminalVoltageWithEveryEffect) {
  Plain inner;
  inner.init_default();
  auto p = params();
  p.contact_resistance_ohm = 2e-3;
  p.hysteresis_v = 0.015;
  p.current_offset_a = 0.01;
  p.current_gain = 0.005;
  All wrapped(inner, p);
  double v_cv = 0.0;
  for (int k = 0; k < 2000; ++k) v_cv = wrapped.step_current(-2.5, kFilm, kDt).voltage_v;
  for (int k = 0; k < 200; ++k) {
    const Plain before = inner;
    const double h_before = wrapped.hysteresis_v();
    const auto r = wrapped.step_voltage(v_cv, kFilm, kDt);
    ASSERT_TRUE(r.valid);
    EXPECT_TRUE(r.converged) << k;
    EXPECT_NEAR(r.voltage_v, v_cv, 1e-8);
    // The same tick driven by the found cell current gives the same voltage and state.
    const double cell_i = (r.current_a - 0.01) / 1.005;
    Plain check = before;
    bms::fw::EffectsModel<Plain, bms::fw::kAllCellEffects> replay(check, p);
    typename All::State s = replay.state();
    s.hysteresis_v = h_before;
    ASSERT_TRUE(replay.restore(s));
    const auto c = replay.step_current(cell_i * 1.005 + 0.01, kFilm, kDt);
    EXPECT_NEAR(c.voltage_v, v_cv, 1e-8);
    EXPECT_NEAR(replay.hysteresis_v(), wrapped.hysteresis_v(), 1e-12);
  }
  EXPECT_LT(wrapped.state().current_a, 0.0);  // still charging in CV
}

TEST(CellEffects, ResyncSeesTheVoltageWithoutTheEffects) {
  Plain a, b;
  a.init_default();
  for (int k = 0; k < 1000; ++k) a.step_current(-2.5, kFilm, kDt);
  b = a;
  auto p = params();
  p.contact_resistance_ohm = 1e-3;
  p.current_offset_a = 0.01;
  All wrapped(b, p);
  const double h = wrapped.hysteresis_v();  // 0: no hysteresis
  const double inv = Plain::inventory_of(0.8408, 0.1592);
  const double v = 3.4, i_meas = -0.2;
  const double cell_i = i_meas - 0.01;
  ASSERT_TRUE(a.resync(v + 1e-3 * cell_i - h, cell_i, kFilm, kDt, inv));
  ASSERT_TRUE(wrapped.resync(v, i_meas, kFilm, kDt, inv));
  EXPECT_TRUE(same_state(a, b));
}

TEST(CellEffects, StateImageRoundTripsAndBadImagesAreRejected) {
  Plain inner;
  inner.init_default();
  auto p = params();
  p.contact_resistance_ohm = 1e-3;
  p.hysteresis_v = 0.01;
  All m(inner, p);
  for (int k = 0; k < 400; ++k) m.step_current(2.0, kFilm, kDt);
  const All::State saved = m.state();
  double first[60];
  for (int k = 0; k < 30; ++k) first[k] = m.step_current(-1.0, kFilm, kDt).voltage_v;
  const double v_cv = first[29];
  for (int k = 30; k < 60; ++k) first[k] = m.step_voltage(v_cv, kFilm, kDt).voltage_v;
  const double h_end = m.hysteresis_v();
  ASSERT_TRUE(m.restore(saved));
  EXPECT_EQ(m.hysteresis_v(), saved.hysteresis_v);
  for (int k = 0; k < 60; ++k) {
    const double v = (k < 30 ? m.step_current(-1.0, kFilm, kDt) : m.step_voltage(v_cv, kFilm, kDt)).voltage_v;
    ASSERT_EQ(v, first[k]) << k;
  }
  EXPECT_EQ(m.hysteresis_v(), h_end);

  const All::State good = m.state();
  All::State bad = good;
  bad.hysteresis_v = std::nan("");
  EXPECT_FALSE(m.restore(bad));
  bad = good;
  bad.hysteresis_v = 0.02;  // beyond H: not a state this model can be in
  EXPECT_FALSE(m.restore(bad));
  bad = good;
  bad.inner.cs_neg_mol_m3[0] = std::nan("");
  EXPECT_FALSE(m.restore(bad));
  const All::State after = m.state();
  EXPECT_EQ(std::memcmp(&after, &good, sizeof(All::State)), 0);  // rejected images change nothing
}

TEST(CellEffects, UnusableParametersAreRefusedAndKeepThePreviousOnes) {
  Plain inner;
  inner.init_default();
  auto p = params();
  p.contact_resistance_ohm = 1e-3;
  All m(inner, p);
  auto bad = p;
  bad.contact_resistance_ohm = -1e-3;
  EXPECT_EQ(bms::fw::invalid_effect_parameter(bad), 1);
  EXPECT_FALSE(m.set_parameters(bad));
  bad = p;
  bad.hysteresis_v = 0.01;
  bad.nominal_capacity_ah = 0.0;
  EXPECT_EQ(bms::fw::invalid_effect_parameter(bad), 5);
  bad = p;
  bad.current_offset_a = std::nan("");
  EXPECT_EQ(bms::fw::invalid_effect_parameter(bad), 6);
  bad = p;
  bad.current_gain = 0.7;
  EXPECT_EQ(bms::fw::invalid_effect_parameter(bad), 7);
  EXPECT_FALSE(m.set_parameters(bad));
  EXPECT_EQ(m.parameters().contact_resistance_ohm, 1e-3);
  EXPECT_EQ(m.parameters().current_gain, 0.0);
}

TEST(CellEffects, BmsCoreRunsOnTheAugmentedModelInDoubleAndFloat) {
  {
    Plain inner;
    inner.init_default();
    auto p = params();
    p.contact_resistance_ohm = 1e-3;
    All m(inner, p);
    using Core = bms::fw::BmsCore<double, All>;
    Core core(Core::Config{}, m);
    for (int k = 0; k < 50; ++k) {
      const auto out = core.tick({3.3, -2.5, true});
      EXPECT_TRUE(std::isfinite(out.model_voltage_v));
    }
    const auto image = core.save();
    EXPECT_TRUE(core.restore(image));
  }
  {
    using PlainF = bms::fw::ReducedCell<float>;
    using AllF = bms::fw::EffectsModel<PlainF, bms::fw::kAllCellEffects>;
    PlainF inner;
    inner.init_default();
    EffectParameters<float> p;
    p.nominal_capacity_ah = 2.3f;
    p.contact_resistance_ohm = 1e-3f;
    p.hysteresis_v = 0.01f;
    p.current_offset_a = 0.01f;
    AllF m(inner, p);
    using Core = bms::fw::BmsCore<float, AllF>;
    Core core(Core::Config{}, m);
    float v_model = 0.0f;
    for (int k = 0; k < 50; ++k) {
      const auto out = core.tick({3.3f, -2.5f, true});
      EXPECT_TRUE(std::isfinite(out.model_voltage_v));
      v_model = out.model_voltage_v;
    }
    const auto cv = m.step_voltage(v_model, static_cast<float>(bms::fw::paper::kInitialFilm_ohm_m2), 0.2f);
    EXPECT_TRUE(cv.valid);
    EXPECT_NEAR(cv.voltage_v, v_model, 1e-4f);
  }
}

}  // namespace
