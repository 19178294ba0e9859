// The reduced model and the tick at the measured temperature (ReducedCell::set_temperature_k,
// BmsCore step 2), and the open-circuit capacity (bms/fw/model/open_circuit_capacity.hpp).
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <limits>

#include "bms/fw/estimation/bms_core.hpp"
#include "bms/fw/config/make_config.hpp"
#include "bms/fw/model/open_circuit_capacity.hpp"
#include "bms/fw/model/reduced_cell.hpp"

namespace {

namespace fw = bms::fw;
using Model = fw::ReducedCell<double>;

// A cell like the paper's with Arrhenius data (the kind a BPX file gives).
struct WarmCellTraits : fw::PaperCellTraits {
  struct Temperature : fw::NoTemperatureData<fw::PaperCellTemperatureBase> {
    static constexpr double kNegDiffusivityActivationJMol = 30e3;
    static constexpr double kPosDiffusivityActivationJMol = 20e3;
    static constexpr double kNegRateActivationJMol = 50e3;
    static constexpr double kPosRateActivationJMol = 40e3;
    static constexpr double kElectrolyteDiffusivityActivationJMol = 15e3;
    static constexpr double kElectrolyteConductivityActivationJMol = 12e3;
    static constexpr bool kHasEntropic = true;
    template <typename T> static T entropic_neg_v_k(T) { return T(-1e-4); }
    template <typename T> static T entropic_pos_v_k(T) { return T(0); }
  };
};

template <class M>
double charge_voltage_after(M& m, int ticks) {
  m.init_default();
  double v = 0.0;
  for (int k = 0; k < ticks; ++k) v = m.step_current(-2.5, 3.391e-3, 0.2).voltage_v;
  return v;
}

TEST(Temperature, AtTheReferenceTheModelIsBitIdenticalToTheIsothermalOne) {
  Model a, b;
  a.init_default();
  b.init_default();
  ASSERT_TRUE(b.set_temperature_k(298.15));
  for (int k = 0; k < 500; ++k) {
    const double i = k < 250 ? 2.5 : -2.5;
    const auto ra = a.step_current(i, 3.391e-3, 0.2), rb = b.step_current(i, 3.391e-3, 0.2);
    ASSERT_EQ(ra.voltage_v, rb.voltage_v) << k;
    ASSERT_EQ(ra.j_side_a_m3, rb.j_side_a_m3) << k;
  }
  EXPECT_EQ(std::memcmp(&a.state(), &b.state(), sizeof(Model::State)), 0);
  // Away and back: the same factors again.
  ASSERT_TRUE(b.set_temperature_k(310.0));
  ASSERT_TRUE(b.set_temperature_k(298.15));
  EXPECT_EQ(a.peek_voltage(-2.5, 3.391e-3, 0.2), b.peek_voltage(-2.5, 3.391e-3, 0.2));
}

TEST(Temperature, FloatAtTheReferenceIsBitIdenticalAndFollowsATemperatureAwayFromIt) {
  fw::ReducedCell<float> a, b;
  a.init_default();
  b.init_default();
  ASSERT_TRUE(b.set_temperature_k(298.15f));
  for (int k = 0; k < 200; ++k) ASSERT_EQ(a.step_current(-2.5f, 3.391e-3f, 0.2f).voltage_v,
                                          b.step_current(-2.5f, 3.391e-3f, 0.2f).voltage_v) << k;
  ASSERT_TRUE(b.set_temperature_k(283.15f));
  const float warm = b.temperature_probe_voltage(-2.5f, 3.391e-3f, 0.2f, 1.0f);
  const float here = b.peek_voltage(-2.5f, 3.391e-3f, 0.2f);
  EXPECT_TRUE(std::isfinite(warm));
  EXPECT_NE(warm, here);
  EXPECT_FALSE(std::isfinite(b.temperature_probe_voltage(-2.5f, 3.391e-3f, 0.2f, 100.0f)));  // out of range
}

TEST(Temperature, ColderMeansMoreOverpotentialAndLessSideReaction) {
  Model cold, ref;
  ASSERT_TRUE(cold.set_temperature_k(278.15));
  const double v_cold = charge_voltage_after(cold, 300), v_ref = charge_voltage_after(ref, 300);
  // Paper cell (no activation energies): only RT/F moves. The charge overpotential is nearly
  // proportional to T in the Tafel range, so it shrinks when cold; measured 1-3 mV at 20 K.
  EXPECT_NE(v_cold, v_ref);
  EXPECT_GT(std::fabs(v_cold - v_ref), 2e-4);
  EXPECT_LT(std::fabs(v_cold - v_ref), 2e-2);
  // The side reaction's exponent alpha F/RT (U_ref - phi) grows when cold: |j_s| changes.
  EXPECT_NE(cold.peek_voltage(-2.5, 3.391e-3, 0.2), ref.peek_voltage(-2.5, 3.391e-3, 0.2));
}

TEST(Temperature, ArrheniusDataMoveTheModelAwayFromTheReferenceOnly) {
  fw::ReducedCell<double, WarmCellTraits> warm_at_ref, warm_cold;
  Model paper;
  // At the reference every factor is 1 and dT = 0: the paper model to the bit.
  EXPECT_EQ(charge_voltage_after(warm_at_ref, 200), charge_voltage_after(paper, 200));
  ASSERT_TRUE(warm_cold.set_temperature_k(268.15));
  Model paper_cold;
  ASSERT_TRUE(paper_cold.set_temperature_k(268.15));
  // Slower kinetics and transport when cold: a larger charge voltage than RT/F alone gives.
  EXPECT_GT(charge_voltage_after(warm_cold, 200), charge_voltage_after(paper_cold, 200) + 1e-3);
}

TEST(Temperature, ImplausibleTemperaturesAreRefusedAndTheLastOneKept) {
  Model m;
  ASSERT_TRUE(m.set_temperature_k(300.0));
  for (double t : {std::numeric_limits<double>::quiet_NaN(), std::numeric_limits<double>::infinity(), -5.0, 100.0,
                   400.0}) {
    EXPECT_FALSE(m.set_temperature_k(t)) << t;
    EXPECT_EQ(m.temperature_k(), 300.0);
  }
}

TEST(Temperature, TheTickPassesTheTemperatureAndFlagsAnImplausibleOne) {
  using Core = fw::BmsCore<double>;
  Model m;
  m.init_default();
  Core core(fw::make_config<Core>(fw::paper_nominal_cell<double>(), fw::Profile::paper), m);
  auto out = core.tick({3.3, 1.0, true});  // no temperature: the reference
  EXPECT_EQ(m.temperature_k(), 298.15);
  out = core.tick({3.3, 1.0, true, 283.15});
  EXPECT_EQ(m.temperature_k(), 283.15);
  EXPECT_FALSE(fw::has_status(out.status, fw::FwStatus::kTemperatureImplausible));
  out = core.tick({3.3, 1.0, true, std::numeric_limits<double>::quiet_NaN()});
  EXPECT_TRUE(fw::has_status(out.status, fw::FwStatus::kTemperatureImplausible));
  EXPECT_EQ(m.temperature_k(), 283.15);
  EXPECT_EQ(out.tick, 3u);  // the sample itself was used
  out = core.tick({3.3, 1.0, true});
  EXPECT_FALSE(fw::has_status(out.status, fw::FwStatus::kTemperatureImplausible));
  EXPECT_EQ(m.temperature_k(), 283.15);
}

TEST(OpenCircuitCapacity, NominalPaperCellAndItsSensitivityToTheInventory) {
  using T = fw::PaperCellTraits;
  const double cap_n = T::kNeg.max_concentration_mol_m3 * T::kNeg.solid_fraction * T::kNeg.thickness_m * T::kAreaM2;
  const double cap_p = T::kPos.max_concentration_mol_m3 * T::kPos.solid_fraction * T::kPos.thickness_m * T::kAreaM2;
  const double n0 = Model::inventory_of(T::kNeg.stoich_init, T::kPos.stoich_init);
  auto un = [](double x) { return T::ocp_neg_v(x); };
  auto up = [](double y) { return T::ocp_pos_v(y); };
  const double c0 = fw::open_circuit_capacity_ah(n0, cap_n, cap_p, 2.0, 3.6, un, up);
  // Between the two limits at rest: below the 2.7 Ah both electrodes could hold, above the
  // 2.3 Ah nominal rating.
  EXPECT_GT(c0, 2.3);
  EXPECT_LT(c0, 2.7);
  // Each limit's stoichiometry pair shows that voltage at rest.
  const double x = fw::equilibrium_stoich_neg(n0, cap_n, cap_p, 3.6, un, up);
  EXPECT_NEAR(up((n0 - x * cap_n) / cap_p) - un(x), 3.6, 1e-9);
  const double c1 = fw::open_circuit_capacity_ah(0.995 * n0, cap_n, cap_p, 2.0, 3.6, un, up);
  EXPECT_NEAR(c1 / c0 - 1.0, -0.005, 0.001);
  // float gives the same to 1e-4 (what the M4F build reports).
  auto unf = [](float v) { return T::ocp_neg_v(v); };
  auto upf = [](float v) { return T::ocp_pos_v(v); };
  const float cf = fw::open_circuit_capacity_ah(static_cast<float>(n0), static_cast<float>(cap_n),
                                                static_cast<float>(cap_p), 2.0f, 3.6f, unf, upf);
  EXPECT_NEAR(static_cast<double>(cf) / c0, 1.0, 1e-4);
  // An inventory no pair of stoichiometries can hold (more than both electrodes together, or
  // none): NaN, not a number that looks right.
  EXPECT_TRUE(std::isnan(fw::open_circuit_capacity_ah(1.01 * (cap_n + cap_p), cap_n, cap_p, 2.0, 3.6, un, up)));
  EXPECT_TRUE(std::isnan(fw::open_circuit_capacity_ah(-0.01 * n0, cap_n, cap_p, 2.0, 3.6, un, up)));
}

// The upper end when the anode is full before the resting cell shows 3.6 V (the paper cell from
// an inventory about 0.85 % above nominal): the anode's full stoichiometry, so the capacity is
// defined, continuous across the change of end, and falls past it.
TEST(OpenCircuitCapacity, TheUpperEndIsTheFullAnodeWhenItIsFullBeforeTheVoltageLimit) {
  using T = fw::PaperCellTraits;
  const double cap_n = T::kNeg.max_concentration_mol_m3 * T::kNeg.solid_fraction * T::kNeg.thickness_m * T::kAreaM2;
  const double cap_p = T::kPos.max_concentration_mol_m3 * T::kPos.solid_fraction * T::kPos.thickness_m * T::kAreaM2;
  const double n0 = Model::inventory_of(T::kNeg.stoich_init, T::kPos.stoich_init);
  auto un = [](double x) { return T::ocp_neg_v(x); };
  auto up = [](double y) { return T::ocp_pos_v(y); };
  auto cap = [&](double scale) { return fw::open_circuit_capacity_ah(scale * n0, cap_n, cap_p, 2.0, 3.6, un, up); };
  // At 1 % more lithium the resting cell never shows 3.6 V: no equilibrium pair, but a window end.
  EXPECT_TRUE(std::isnan(fw::equilibrium_stoich_neg(1.01 * n0, cap_n, cap_p, 3.6, un, up)));
  const double x_full = fw::window_end_stoich_neg(1.01 * n0, cap_n, cap_p, 3.6, un, up);
  EXPECT_NEAR(x_full, 1.0 - 1e-6, 1e-12);
  EXPECT_LT(up((1.01 * n0 - x_full * cap_n) / cap_p) - un(x_full), 3.6);
  ASSERT_TRUE(std::isfinite(cap(1.01)));
  EXPECT_NEAR(cap(1.01) / cap(1.0), 1.0076, 0.002);
  // Where both limits are reached, the window end is the equilibrium stoichiometry bit for bit.
  EXPECT_EQ(fw::window_end_stoich_neg(n0, cap_n, cap_p, 3.6, un, up),
            fw::equilibrium_stoich_neg(n0, cap_n, cap_p, 3.6, un, up));
  // Find the change of end (bisection on the inventory): continuous there, falling past it.
  double a = 1.0, b = 1.01;
  for (int i = 0; i < 40; ++i) {
    const double m = 0.5 * (a + b);
    (std::isnan(fw::equilibrium_stoich_neg(m * n0, cap_n, cap_p, 3.6, un, up)) ? b : a) = m;
  }
  EXPECT_GT(a, 1.005);
  EXPECT_LT(a, 1.01);
  EXPECT_NEAR(cap(a), cap(b), 1e-6);
  EXPECT_GT(cap(a), cap(a + 0.005));
  EXPECT_GT(cap(a + 0.005), cap(a + 0.01));
  // The same in float (the M4F).
  auto unf = [](float v) { return T::ocp_neg_v(v); };
  auto upf = [](float v) { return T::ocp_pos_v(v); };
  const float cf = fw::open_circuit_capacity_ah(static_cast<float>(1.01 * n0), static_cast<float>(cap_n),
                                                static_cast<float>(cap_p), 2.0f, 3.6f, unf, upf);
  EXPECT_NEAR(static_cast<double>(cf) / cap(1.01), 1.0, 1e-4);
}

}  // namespace
