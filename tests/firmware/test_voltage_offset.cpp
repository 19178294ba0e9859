// The voltage sensor's offset: its stated accuracy in the film's sd
// (IdentifierFilmPath::Config::voltage_offset_sd_v).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "bms/fw/estimation/identifier_film_path.hpp"
#include "film_path_learning.hpp"

namespace {

namespace fw = bms::fw;
using Path = fw::IdentifierFilmPath<double>;

constexpr double kChargeA = fw::test::kPathChargeA;
constexpr double kFilmOhmM2 = 3.391e-3;
constexpr double kDtS = fw::test::kPathDtS;
constexpr double kH = fw::test::kPathH;

struct NoSpreadModel {};

Path::Config path_config(double voltage_sd_v) {
  Path::Config c = bms::fw::test::plain_path_config(kFilmOhmM2);
  c.voltage_offset_sd_v = voltage_sd_v;
  return c;
}

// The stated accuracy widens the fitted level's sd by sd_v / H in quadrature and changes nothing
// else: not the fit, not the reported level (no combination with the prior), not the held prior.
TEST(VoltageOffsetSd, TheStatedAccuracyOverHEntersTheFittedSdInQuadrature) {
  const double sd_v = 0.2887e-3;
  Path stated(path_config(sd_v), kDtS), plain(path_config(0.0), kDtS);
  EXPECT_EQ(stated.film_sd_ohm_m2(), plain.film_sd_ohm_m2());  // the held prior: the prior's sd
  fw::test::learn_ticks(stated, NoSpreadModel{}, 200, 1.1 * kFilmOhmM2);
  fw::test::learn_ticks(plain, NoSpreadModel{}, 200, 1.1 * kFilmOhmM2);
  ASSERT_FALSE(stated.holding());
  EXPECT_EQ(stated.identifier().film_ohm_m2(), plain.identifier().film_ohm_m2());
  EXPECT_EQ(stated.r_film_ohm_m2(), plain.r_film_ohm_m2());
  EXPECT_NEAR(stated.film_voltage_offset_ohm_m2(), sd_v / kH, 1e-15);
  EXPECT_EQ(plain.film_voltage_offset_ohm_m2(), 0.0);
  const double s0 = plain.film_sd_ohm_m2(), s1 = stated.film_sd_ohm_m2();
  EXPECT_NEAR(s1 * s1, s0 * s0 + (sd_v / kH) * (sd_v / kH), 1e-12 * s1 * s1);
  EXPECT_GT(s1, 2.0 * s0);  // 0.29 mV is about 9 % of this film: wider than the model bound
  std::printf("fitted sd %.3g -> %.3g ohm m2 (%.1f %% of the film) with %.3g mV stated\n", s0, s1,
              100.0 * s1 / (1.1 * kFilmOhmM2), sd_v * 1e3);
}

}  // namespace

#include "bms/fw/estimation/voltage_offset.hpp"

namespace {

using Offset = bms::fw::VoltageOffset<double>;

Offset::Config offset_config() {
  Offset::Config c;
  c.enabled = true;
  c.model_bias_ohm = 0.0;
  return c;
}

// A fitted charge (its learning ticks at H_c), then a CC discharge whose residual after the warm-up
// is z (H_d = -H_c: the film's drop has the other sign), then the phase ends.
bool charge_then_discharge(Offset& o, double z_v, bool holding = false, int fitted_ticks = 3000) {
  for (int k = 0; k < fitted_ticks; ++k) o.follow(false, holding, true, 0.0, kChargeA, kH);
  const int discharge_ticks = 900 * 5 + 1600;  // the warm-up, then 1600 collected ticks
  for (int k = 0; k < discharge_ticks; ++k) o.follow(true, holding, false, z_v, 2.5, -kH);
  return o.follow(false, holding, false, 0.0, 0.0, 0.0);  // CV discharge: the phase ends
}

// The discharge's residual after a fitted charge is -(1 - H_d / H_c) b = -2 b: b is fused and
// subtracted from every later sample; a remainder inside the dead band changes nothing.
TEST(VoltageOffset, TheDischargeResidualAfterAFittedChargeGivesTheOffset) {
  Offset o(offset_config());
  EXPECT_EQ(o.corrected(3.7), 3.7);
  EXPECT_TRUE(charge_then_discharge(o, -2.0 * 0.4e-3));
  EXPECT_NEAR(o.offset_v(), 0.4e-3, 1e-12);
  EXPECT_NEAR(o.corrected(3.7), 3.7 - 0.4e-3, 1e-12);
  // The next charge is fitted on the corrected voltage: a remainder of 0.05 mV is inside the band.
  EXPECT_FALSE(charge_then_discharge(o, -2.0 * 0.05e-3));
  EXPECT_NEAR(o.offset_v(), 0.4e-3, 1e-12);
  EXPECT_NEAR(o.last_remainder_v(), 0.05e-3, 1e-12);
  // One outside it moves the offset in use by the remainder.
  EXPECT_TRUE(charge_then_discharge(o, 2.0 * 0.15e-3));
  EXPECT_NEAR(o.offset_v(), 0.25e-3, 1e-12);
}

// Start and stop conditions: nothing without a fitted charge, while the path holds a restarted fit,
// for a remainder no front end has, or when off.
TEST(VoltageOffset, NothingIsFusedWithoutAFittedSettledChargeOrBeyondTheLimit) {
  Offset a(offset_config()), b(offset_config()), c(offset_config());
  EXPECT_FALSE(charge_then_discharge(a, -0.8e-3, false, 100));  // 100 learning ticks: not a fitted charge
  EXPECT_FALSE(charge_then_discharge(b, -0.8e-3, true));        // the path holds: the fit is not settled
  EXPECT_FALSE(charge_then_discharge(c, -2.0 * 6e-3));          // 6 mV: over the 5 mV limit
  EXPECT_EQ(a.offset_v() + b.offset_v() + c.offset_v(), 0.0);
  Offset::Config off = offset_config();
  off.enabled = false;
  Offset d(off);
  EXPECT_FALSE(charge_then_discharge(d, -0.8e-3));
  EXPECT_EQ(d.corrected(3.7), 3.7);
  // A restored image with an offset over the limit is refused.
  Offset::State s = Offset(offset_config()).save();
  s.offset_v = 6e-3;
  EXPECT_FALSE(a.restore(s));
  s.offset_v = 0.3e-3;
  EXPECT_TRUE(a.restore(s));
  EXPECT_NEAR(a.offset_v(), 0.3e-3, 1e-15);
}

}  // namespace
