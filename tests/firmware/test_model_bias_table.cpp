// The design-time bias as a function of the state of charge (ModelBiasTable): its lookup (linear
// between evenly spaced knots, the end knot's value outside, 0 when off) and its use in the
// identifier's path (the constant plus the table at the model's mean anode stoichiometry; a path
// without a table, or a model without a stoichiometry, runs on the constant bit for bit), and that
// a charge whose model error varies with the state of charge is identified right with the table
// and wrong with its median alone. Its levels over the lithium inventory (ModelBiasTables): read
// where the model is placed, their slope added to the inventory's sensitivity.
#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <utility>

#include "bms/fw/estimation/identifier_film_path.hpp"
#include "bms/fw/estimation/learning_gate.hpp"
#include "bms/fw/estimation/state_resync.hpp"
#include "bms/fw/model/model_bias_table.hpp"

namespace {

using Table = bms::fw::ModelBiasTable<double>;
using Tables = bms::fw::ModelBiasTables<double>;
using Path = bms::fw::IdentifierFilmPath<double>;
constexpr int kN = Table::kKnots;

// Knots 0.2 .. 0.7, bias -0.5 .. +0.5 mohm, a kink at the middle knot.
Table ramp() {
  Table t;
  t.x_first = 0.2;
  t.x_last = 0.7;
  for (int k = 0; k < kN; ++k) t.ohm[k] = k <= kN / 2 ? 1e-3 * (double(k) / (kN - 1) - 0.5) : 2e-4;
  return t;
}

struct StoichModel {
  double x;
  double mean_stoich_neg() const { return x; }
};
struct PlainModel {};

TEST(ModelBiasTable, OffIsZeroAndValid) {
  const Table off;
  EXPECT_FALSE(off.on());
  EXPECT_TRUE(off.valid());
  EXPECT_EQ(off.at(0.5), 0.0);
}

TEST(ModelBiasTable, LinearBetweenKnotsEndValuesOutside) {
  const Table t = ramp();
  ASSERT_TRUE(t.on());
  ASSERT_TRUE(t.valid());
  const double step = (t.x_last - t.x_first) / (kN - 1);
  for (int k = 0; k < kN; ++k) EXPECT_NEAR(t.at(t.x_first + k * step), t.ohm[k], 1e-15) << "knot " << k;
  for (int k = 0; k + 1 < kN; ++k) {
    const double x = t.x_first + (k + 0.25) * step;
    EXPECT_NEAR(t.at(x), 0.75 * t.ohm[k] + 0.25 * t.ohm[k + 1], 1e-15) << "between knots " << k << " and " << k + 1;
  }
  EXPECT_EQ(t.at(0.0), t.ohm[0]);
  EXPECT_EQ(t.at(1.0), t.ohm[kN - 1]);
  EXPECT_EQ(t.at(std::numeric_limits<double>::quiet_NaN()), 0.0);
  const auto f = t.as<float>();
  EXPECT_NEAR(f.at(0.33f), t.at(0.33), 1e-9);
}

TEST(ModelBiasTable, InvalidTablesAreSaid) {
  Table t = ramp();
  t.ohm[3] = std::numeric_limits<double>::infinity();
  EXPECT_FALSE(t.valid());
  t = ramp();
  t.x_last = 0.1;  // decreasing span
  EXPECT_FALSE(t.valid());
}

TEST(ModelBiasTable, PathAddsTheTableAtTheModelsStoichiometry) {
  Path::Config pc;
  pc.model_bias_ohm = 3.0e-4;
  const Path constant_only(pc, 0.2);
  EXPECT_EQ(constant_only.model_bias_ohm_of(StoichModel{0.4}), 3.0e-4) << "no table: the constant, bit for bit";
  pc.model_bias_table.nominal() = ramp();
  const Path with_table(pc, 0.2);
  for (double x : {0.1, 0.25, 0.45, 0.6, 0.9})
    EXPECT_EQ(with_table.model_bias_ohm_of(StoichModel{x}), 3.0e-4 + ramp().at(x)) << "x = " << x;
  EXPECT_EQ(with_table.model_bias_ohm_of(PlainModel{}), 3.0e-4) << "a model without a stoichiometry: the constant";
}

// One CC charge at 2 A whose model error is the table's shape over x = 0.2 .. 0.7: z = H (u - R) +
// S (0 - nu) + b(x) I_charge, less a knee past x = 0.62 that the table does not hold (knee_v x the
// square of the knee's fraction, knee_v at x = 0.7). Returns the identified film's relative error;
// *learned_past (if given) counts the learned ticks past x_stop.
double film_error_of_charge(const Path::Config& pc, double knee_v = 0.0, double x_stop = 1.0,
                            int* learned_past = nullptr) {
  constexpr double kFilm = 3.7e-3, kH = 1.0, kI = -2.0, kKneeX = 0.62;
  Path path(pc, 0.2);
  bms::fw::LearningGate<double> gate(bms::fw::LearningGate<double>::Config{});
  const bms::fw::StateResync<double> resync(bms::fw::StateResync<double>::Config{});
  constexpr int kTicks = 6000;
  int past = 0;
  for (int k = 0; k < kTicks; ++k) {
    const double x = 0.2 + 0.5 * k / (kTicks - 1);
    const double knee = x > kKneeX ? (x - kKneeX) / (0.7 - kKneeX) : 0.0;
    const double s_v = 0.3 + 0.5 * k / kTicks;
    const double u = path.film_in_use(true);
    const double z = kH * (u - kFilm) - ramp().at(x) * kI - knee_v * knee * knee;
    bms::fw::ModelTickResult<double> r{3.5, kI, -1e3, kH, 0u, true, true};
    const bms::fw::FilmTick<double> t{r, kI, u, z, 3.5 + s_v * 1e-3, 0.2, 1.0, true, true};
    const auto l = path.learn(t, StoichModel{x}, gate, resync);
    if (x > x_stop && l.active) ++past;
  }
  if (learned_past != nullptr) *learned_past = past;
  return (path.identifier().film_ohm_m2() - kFilm) / kFilm;
}

// The path of the synthetic charges: a nominal film 8 % below theirs, the ramp's table.
Path::Config charge_config() {
  Path::Config pc;
  pc.identifier.r_film_nominal_ohm_m2 = 3.4e-3;
  pc.identifier.growth_nominal_ohm_m2_per_a_m3_s = 1e-12;
  pc.temperature_sd_k = 0.0;
  pc.model_bias_table.nominal() = ramp();
  return pc;
}

TEST(ModelBiasTable, ChargeWithAStateDependentErrorIsIdentifiedWithTheTable) {
  Path::Config pc = charge_config();
  const double with_table = film_error_of_charge(pc);
  pc.model_bias_table = Tables{};
  pc.model_bias_ohm = ramp().at(0.45);  // the table's median over the charge, as a constant
  const double constant_only = film_error_of_charge(pc);
  EXPECT_LT(std::fabs(with_table), 1e-3) << "the table removes the model's error";
  EXPECT_GT(std::fabs(constant_only), 0.02) << "the median alone leaves its shape in the film";
}

TEST(ModelBiasTable, LearningStopsPastTheTrustedSpan) {
  Path::Config pc = charge_config();
  int learned_past = 0;
  const double everywhere = film_error_of_charge(pc, 0.05, 0.6, &learned_past);
  EXPECT_GT(learned_past, 0) << "x_trusted_last +inf (the default): every tick is learned";
  EXPECT_GT(std::fabs(everywhere), 0.02) << "the knee, learned, moves the film";
  pc.model_bias_table.set_trusted_last(0.6);
  const double trusted = film_error_of_charge(pc, 0.05, 0.6, &learned_past);
  EXPECT_EQ(learned_past, 0) << "no tick past the span's end is learned";
  EXPECT_LT(std::fabs(trusted), 1e-3) << "the span before the knee identifies the film";
  EXPECT_TRUE(pc.model_bias_table.valid());
  pc.model_bias_table.set_trusted_last(std::numeric_limits<double>::quiet_NaN());
  EXPECT_FALSE(pc.model_bias_table.valid());
  EXPECT_EQ(ramp().as<float>().x_trusted_last, std::numeric_limits<float>::infinity());
}

// The table's start condition: a charge whose learning opens more than bias_table_start_margin of
// the table's span above its first knot (a partial charge begun mid-window) runs on the constant
// alone until the next charge; one that opens near the first knot reads the table; an infinite
// margin (--bias-table-any-start) reads it in every charge.
double bias_after_opening_at(const Path::Config& pc, double x_open, double x_read) {
  Path path(pc, 0.2);
  bms::fw::LearningGate<double> gate(bms::fw::LearningGate<double>::Config{});
  const bms::fw::StateResync<double> resync(bms::fw::StateResync<double>::Config{});
  const double u = path.film_in_use(true);
  bms::fw::ModelTickResult<double> r{3.5, -2.0, -1e3, 1.0, 0u, true, true};
  const bms::fw::FilmTick<double> t{r, -2.0, u, 0.0, 3.5003, 0.2, 1.0, true, true};
  path.learn(t, StoichModel{x_open}, gate, resync);
  return path.model_bias_ohm_of(StoichModel{x_read});
}

TEST(ModelBiasTable, ATableAppliesOnlyToChargesBegunWhereItsCalibrationsBegan) {
  Path::Config pc = charge_config();
  pc.model_bias_ohm = 3.0e-4;
  ASSERT_EQ(pc.bias_table_start_margin, 0.1);  // of the span 0.2 .. 0.7: opening above x = 0.25
  EXPECT_EQ(bias_after_opening_at(pc, 0.21, 0.45), 3.0e-4 + ramp().at(0.45)) << "begun at the bottom";
  EXPECT_EQ(bias_after_opening_at(pc, 0.249, 0.45), 3.0e-4 + ramp().at(0.45)) << "within the margin";
  EXPECT_EQ(bias_after_opening_at(pc, 0.40, 0.45), 3.0e-4) << "begun mid-window: the constant alone";
  pc.bias_table_start_margin = std::numeric_limits<double>::infinity();
  EXPECT_EQ(bias_after_opening_at(pc, 0.40, 0.45), 3.0e-4 + ramp().at(0.45)) << "the ablation: every charge";
}

// Levels over the inventory: the nominal level alone without a step, bit for bit; with one, the
// parabola through the three levels within +-step (the end level's value outside, slope 0 there),
// its slope the parabola's derivative; the trusted span's end linear where both ends are finite.
TEST(ModelBiasTables, LevelsAreReadAtTheInventoryDeviation) {
  Tables t;
  t.nominal() = ramp();
  EXPECT_FALSE(t.by_inventory());
  for (double nu : {-0.02, 0.0, 0.004, 0.03}) EXPECT_EQ(t.at(0.41, nu), ramp().at(0.41)) << "no step: nominal";
  EXPECT_EQ(t.slope(0.41, 0.0), 0.0);
  Table lean = ramp(), rich = ramp();
  for (int k = 0; k < kN; ++k) {
    lean.ohm[k] -= 1e-4;
    rich.ohm[k] += 3e-4;
  }
  lean.x_trusted_last = 0.60;
  t.nominal().x_trusted_last = 0.64;
  t.level[0] = lean;
  t.level[2] = rich;
  t.nu_step = 0.01;
  ASSERT_TRUE(t.valid());
  const double x = 0.41, b = ramp().at(x);
  // Through (-1, -1e-4), (0, 0), (1, 3e-4) in units of the step: 2e-4 s + 1e-4 s^2.
  const auto parabola = [](double s) { return 2e-4 * s + 1e-4 * s * s; };
  for (double nu : {-0.01, -0.0025, 0.0, 0.005, 0.01}) {
    EXPECT_NEAR(t.at(x, nu), b + parabola(nu / 0.01), 1e-15) << "nu = " << nu;
    EXPECT_NEAR(t.slope(x, nu), (parabola(nu / 0.01 + 1e-6) - parabola(nu / 0.01 - 1e-6)) / 2e-8, 1e-9) << "nu = " << nu;
  }
  EXPECT_NEAR(t.at(x, 0.05), b + 3e-4, 1e-15) << "the rich level's value beyond it";
  EXPECT_NEAR(t.at(x, -0.05), b - 1e-4, 1e-15) << "the lean level's value below it";
  EXPECT_EQ(t.slope(x, 0.05), 0.0) << "flat beyond the levels";
  EXPECT_NEAR(t.at(x, std::numeric_limits<double>::quiet_NaN()), b, 1e-15) << "no inventory: nominal";
  EXPECT_NEAR(t.trusted_last(-0.005), 0.62, 1e-12);
  EXPECT_EQ(t.trusted_last(0.002), 0.64) << "the rich level's end is +inf: the nearer level's";
  EXPECT_TRUE(std::isinf(t.trusted_last(0.008)));
  EXPECT_NEAR(t.as<float>().at(0.41f, 0.005f), t.at(x, 0.005), 1e-9);
  t.drop_knots();
  EXPECT_FALSE(t.on());
  EXPECT_EQ(t.slope(x, 0.0), 0.0);
  EXPECT_NEAR(t.trusted_last(-0.005), 0.62, 1e-12) << "--no-bias-table keeps each level's span";
  t.nu_step = -0.01;
  EXPECT_FALSE(t.valid());
}

// The calibration's coverage (ModelBiasTables::covers): a charge below the lowest covered current,
// or one that runs on the constant alone where the constant does not fit, is not covered; the
// defaults cover every charge.
TEST(ModelBiasTables, CoverAChargeByItsCurrentAndItsStart) {
  Tables t;
  EXPECT_TRUE(t.covers(0.01, false)) << "the defaults: every charge";
  t.covered_charge_a_min = 1.5;
  EXPECT_FALSE(t.covers(1.4, true));
  EXPECT_TRUE(t.covers(1.5, true));
  t.constant_alone_covered = false;
  EXPECT_TRUE(t.covers(2.0, false)) << "no table: the constant is the whole bias, the calibration's own";
  t.nominal() = ramp();
  EXPECT_FALSE(t.covers(2.0, false)) << "on the constant alone where only the table fits";
  EXPECT_TRUE(t.covers(2.0, true));
  t.covered_charge_a_min = -1.0;
  EXPECT_FALSE(t.valid());
  EXPECT_EQ(t.as<float>().constant_alone_covered, false);
  EXPECT_EQ(t.as<float>().covered_charge_a_min, -1.0f);
}

// A charge the calibration does not cover is not learned from: the film stays the prior's (8 %
// below the charge's; it grows by its law, 0.03 % over the charge); covered, the same charge
// identifies it.
TEST(ModelBiasTables, AChargeTheCalibrationDoesNotCoverIsNotLearned) {
  const double prior_error = (3.4e-3 - 3.7e-3) / 3.7e-3;
  Path::Config pc = charge_config();
  pc.model_bias_table.covered_charge_a_min = 1.0;  // the charge runs at 2 A
  EXPECT_LT(std::fabs(film_error_of_charge(pc)), 1e-3);
  pc.model_bias_table.covered_charge_a_min = 2.5;
  EXPECT_NEAR(film_error_of_charge(pc), prior_error, 1e-3) << "below the covered current (the prior and its growth)";
  pc.model_bias_table.covered_charge_a_min = 0.0;
  pc.bias_table_start_margin = -1.0;  // the charge opens above the margin: the constant alone
  EXPECT_GT(std::fabs(film_error_of_charge(pc) - prior_error), 1e-3) << "the constant alone, covered: learned";
  pc.model_bias_table.constant_alone_covered = false;
  EXPECT_NEAR(film_error_of_charge(pc), prior_error, 1e-3) << "the constant alone, not covered";
}

// The identifier's path reads the levels at the inventory its model was last placed at
// (StateResync::inventory_deviation_model), not at the nominal one, and adds the bias's slope over
// the inventory to the inventory's sensitivity (S = dV/dnu, the residual's regressor).
TEST(ModelBiasTables, PathReadsTheLevelAtTheModelsInventory) {
  Path::Config pc = charge_config();
  Table rich = ramp();
  for (double& v : rich.ohm) v += 5e-4;
  pc.model_bias_table.level[0] = ramp();
  pc.model_bias_table.level[2] = rich;
  pc.model_bias_table.nu_step = 0.01;
  // Its single ticks open a charge mid-table: the start condition (tested above) is not the subject.
  pc.bias_table_start_margin = std::numeric_limits<double>::infinity();
  const double at_nominal = film_error_of_charge(pc);
  EXPECT_LT(std::fabs(at_nominal), 1e-3) << "a resync that never ran: the model at nominal, the nominal level";
  const auto first_tick = [&](double nu_model) {
    Path path(pc, 0.2);
    bms::fw::LearningGate<double> gate(bms::fw::LearningGate<double>::Config{});
    bms::fw::StateResync<double> resync(bms::fw::StateResync<double>::Config{});
    if (nu_model != 0.0) resync.succeeded(nu_model, 1.0);
    bms::fw::ModelTickResult<double> r{3.5, -2.0, -1e3, 1.0, 0u, true, true};
    const bms::fw::FilmTick<double> tick{r, -2.0, 3.4e-3, 0.0, 3.5 + 0.3e-3 * 1e-3, 0.2, 1.0, true, true};
    const auto l = path.learn(tick, StoichModel{0.45}, gate, resync);
    return std::pair{path.model_bias_ohm_of(StoichModel{0.45}), l.inventory_sensitivity_v};
  };
  const auto [bias_rich, s_rich] = first_tick(0.01);
  EXPECT_NEAR(bias_rich, rich.at(0.45), 1e-15) << "placed at +1 %: the rich level";
  const auto [bias_nominal, s_nominal] = first_tick(0.0);
  EXPECT_NEAR(bias_nominal, ramp().at(0.45), 1e-15);
  pc.model_bias_table.nu_step = 0.0;
  const auto [bias_one, s_one] = first_tick(0.0);
  EXPECT_EQ(bias_one, ramp().at(0.45));
  EXPECT_NEAR(s_nominal - s_one, -2.0 * (0.5 * 5e-4 / 0.01), 1e-12)
      << "S gains I x the bias's slope over the inventory (half the rich-lean difference per step at nominal)";
}

}  // namespace
