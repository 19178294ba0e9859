// The firmware tick: input validation, modes, RCSI activation, staleness, save/restore.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>

#include "bms/fw/estimation/bms_core.hpp"
#include "bms/fw/model/paper_cell.hpp"

namespace {

using bms::fw::FwStatus;
using bms::fw::Mode;
using Model = bms::fw::ReducedCell<double>;
using Core = bms::fw::BmsCore<double, Model, 1, 0>;

struct Rig {
  Model truth, model;
  Core core;
  double r_true = 3.45e-3;  // differs from the estimator's 3.391e-3 start
  Rig() : core(Core::Config{}, model) {
    truth.init_default();
    model.init_default();
  }
  // Truth sample from the same reduced model with a known film (a synthetic plant).
  bms::fw::TickInput<double> sample(double current_a) {
    const auto r = truth.step_current(current_a, r_true, 0.2);
    return {r.voltage_v, current_a, true};
  }
};

bool same_state(const Core& a, const Core& b) {
  const auto sa = a.save(), sb = b.save();
  return std::memcmp(&sa, &sb, sizeof(sa)) == 0;
}

TEST(BmsCore, RejectsBadSamplesAndKeepsState) {
  Rig rig;
  for (int i = 0; i < 20; ++i) rig.core.tick(rig.sample(2.5));
  const auto before = rig.core.save();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  struct Case { double v, i; FwStatus bit; } cases[] = {
      {nan, 2.5, FwStatus::kSampleNonFinite}, {3.3, nan, FwStatus::kSampleNonFinite},
      {inf, 2.5, FwStatus::kSampleNonFinite}, {3.3, -inf, FwStatus::kSampleNonFinite},
      {-0.1, 2.5, FwStatus::kVoltageOutOfRange}, {5.2, 2.5, FwStatus::kVoltageOutOfRange},
      {3.3, 250.0, FwStatus::kCurrentImplausible}, {3.3, -19.0, FwStatus::kCurrentImplausible}};
  for (const auto& c : cases) {
    const auto out = rig.core.tick({c.v, c.i, true});
    EXPECT_TRUE(bms::fw::has_status(out.status, c.bit)) << c.v << " " << c.i;
    EXPECT_TRUE(std::isfinite(out.r_film_est_ohm_m2));
    // The estimator, model and detector states are untouched (only the staleness counter
    // moves), and no NaN leaves the tick.
    auto now = rig.core.save();
    EXPECT_EQ(std::memcmp(&now.model, &before.model, sizeof(now.model)), 0);
    EXPECT_EQ(std::memcmp(&now.film_path.estimator, &before.film_path.estimator, sizeof(now.film_path.estimator)), 0);
    rig.core.tick(rig.sample(2.5));  // a good sample in between resets staleness
    rig.core.restore(before);
  }
}

TEST(BmsCore, MissingSamplesFreezeThenResume) {
  Rig rig;
  for (int i = 0; i < 20; ++i) rig.core.tick(rig.sample(2.5));
  const auto before = rig.core.save();
  bms::fw::StatusWord st = 0;
  for (int i = 0; i < 2; ++i) st |= rig.core.tick({0, 0, false}).status;
  EXPECT_FALSE(bms::fw::has_status(st, FwStatus::kMeasurementStale));  // 2 ticks tolerated
  const auto third = rig.core.tick({0, 0, false});
  EXPECT_TRUE(bms::fw::has_status(third.status, FwStatus::kMeasurementStale));
  auto now = rig.core.save();
  EXPECT_EQ(std::memcmp(&now.film_path.estimator, &before.film_path.estimator, sizeof(now.film_path.estimator)), 0);
  const auto back = rig.core.tick(rig.sample(2.5));
  EXPECT_FALSE(bms::fw::has_status(back.status, FwStatus::kMeasurementStale));
  EXPECT_EQ(back.tick, before.ticks + 1);
}

// Lost samples in CC: at the next accepted sample the model steps over the missed ticks,
// so it stays with the cell instead of falling 0.2 s of charge behind per lost sample.
struct GapRig {
  Model truth, model;
  Core core;
  double film;
  explicit GapRig(const Core::Config& cfg) : core(cfg, model), film(cfg.film_path.estimator.r_film_init_ohm_m2) {
    truth.init_default();  // plant = model and the same film: only the lag differs
    model.init_default();
  }
  Core::Output sample(bool delivered) {
    const auto r = truth.step_current(2.5, film, 0.2);
    return core.tick({r.voltage_v, 2.5, delivered});
  }
  Core::Output gap(int lost) {
    for (int i = 0; i < 20; ++i) sample(true);
    for (int i = 0; i < lost; ++i) sample(false);
    return sample(true);
  }
  double lag() const { return std::abs(model.mean_stoich_neg() - truth.mean_stoich_neg()); }
};

TEST(BmsCore, CatchUpKeepsTheModelWithTheCellAcrossLostSamples) {
  Core::Config one_step_per_tick;
  one_step_per_tick.catch_up_max_steps = 10u;
  GapRig exact(one_step_per_tick);
  const auto back = exact.gap(10);
  EXPECT_EQ(exact.core.catch_up_ticks(), 10u);
  EXPECT_LT(exact.lag(), 1e-12);  // the same ten 0.2 s steps the plant took
  EXPECT_LT(std::abs(back.z_v), 1e-9);

  GapRig bounded{Core::Config{}};  // default: at most 8 steps, here 8 steps of 0.25 s
  const auto bounded_back = bounded.gap(10);
  EXPECT_LT(bounded.lag(), 1e-9);  // the charge moved is exact
  EXPECT_LT(std::abs(bounded_back.z_v), 1e-5);

  Core::Config off;
  off.catch_up_max_ticks = 0u;
  GapRig frozen(off);
  frozen.gap(10);
  EXPECT_EQ(frozen.core.catch_up_ticks(), 0u);
  EXPECT_GT(frozen.lag(), 1e-5);  // 10 ticks of 2.5 A behind
}

// The application reports ticks that never reached tick() (bus down, a restart): the same
// staleness and the same catch-up as ticks without a sample.
TEST(BmsCore, TicksMissedCountLikeTicksWithoutASample) {
  Core::Config one_step_per_tick;
  one_step_per_tick.catch_up_max_steps = 10u;
  GapRig via_tick(one_step_per_tick), via_app(one_step_per_tick);
  via_tick.gap(10);
  for (int i = 0; i < 20; ++i) via_app.sample(true);
  for (int i = 0; i < 10; ++i) via_app.truth.step_current(2.5, via_app.film, 0.2);
  via_app.core.ticks_missed(10);
  EXPECT_TRUE(bms::fw::has_status(via_app.core.status(), FwStatus::kMeasurementStale));
  via_app.sample(true);
  EXPECT_EQ(via_app.core.catch_up_ticks(), 10u);
  EXPECT_EQ(std::memcmp(&via_app.model.state(), &via_tick.model.state(), sizeof(via_tick.model.state())), 0);
}

// A 2-minute gap (the firmware restarted from a state committed a minute earlier, or the bus
// down) in 8 long implicit steps: charge exact, voltage close.
TEST(BmsCore, CatchUpOverALongGapInBoundedSteps) {
  GapRig rig{Core::Config{}};
  const auto back = rig.gap(600);
  EXPECT_EQ(rig.core.catch_up_ticks(), 600u);
  EXPECT_LT(rig.lag(), 1e-8);
  EXPECT_LT(std::abs(back.z_v), 0.5e-3);
  Core::Config off;
  off.catch_up_max_ticks = 0u;
  GapRig frozen(off);
  const auto frozen_back = frozen.gap(600);
  EXPECT_GT(std::abs(frozen_back.z_v), 10.0 * std::abs(back.z_v));
  std::printf("600-tick gap in CC: residual after it %.4f mV with catch-up, %.4f mV without\n", back.z_v * 1e3,
              frozen_back.z_v * 1e3);
}

// A record that stops under current and resumes after a long pause (a stopped test, the BMS
// off): beyond power_cycle_after_s the model rests over the gap, as the cell did, and
// re-synchronises at the first sample; the lost-frame catch-up would interpolate the last
// current over the whole pause.
TEST(BmsCore, APowerCycleGapIsARestAndAResync) {
  auto run = [](double power_cycle_after_s) {
    Core::Config cfg;
    cfg.power_cycle_after_s = power_cycle_after_s;
    cfg.resync_at_start = true;
    Model design;
    design.init_default();
    cfg.nominal_inventory_mol = Model::inventory_of(design.mean_stoich_neg(), design.mean_stoich_pos());
    GapRig rig(cfg);
    for (int i = 0; i < 20; ++i) rig.sample(true);
    const std::uint32_t resyncs_before = rig.core.resync_count();
    for (int i = 0; i < 3000; ++i) rig.truth.step_current(0.0, rig.film, 0.2);  // the cell rests
    rig.core.ticks_missed(3000u);
    const auto r = rig.truth.step_current(0.0, rig.film, 0.2);
    rig.core.tick({r.voltage_v, 0.0, true});
    return std::make_pair(rig.lag(), rig.core.resync_count() - resyncs_before);
  };
  const auto [lag_power_cycle, resyncs] = run(200.0);  // 1000 ticks
  const auto [lag_interpolated, resyncs_off] = run(0.0);
  EXPECT_LT(lag_power_cycle, 1e-6);
  EXPECT_GT(lag_interpolated, 100.0 * lag_power_cycle + 1e-4);  // half the gap at ~1.25 A
  EXPECT_EQ(resyncs_off, 0u);
  EXPECT_EQ(resyncs, 1u);
  std::printf("3000-tick pause after a 2.5 A discharge: stoichiometry lag %.2e as a power cycle, %.2e "
              "interpolated; %u re-synchronisation(s)\n",
              lag_power_cycle, lag_interpolated, resyncs);
}

TEST(BmsCore, RcsiLearnsOnlyInConstantCurrentChargeAndTracksTheFilm) {
  Rig rig;
  int active_outside = 0, active_inside = 0;
  Core::Output last{};
  for (int i = 0; i < 300; ++i) {  // discharge: not identifiable
    last = rig.core.tick(rig.sample(2.5));
    active_outside += last.rcsi_active;
  }
  EXPECT_EQ(last.mode, Mode::cc_discharge);
  EXPECT_DOUBLE_EQ(last.r_film_est_ohm_m2, bms::fw::paper::kInitialFilm_ohm_m2);  // held
  for (int i = 0; i < 3000; ++i) {
    last = rig.core.tick(rig.sample(-2.5));
    active_inside += last.rcsi_active;
  }
  EXPECT_EQ(last.mode, Mode::cc_charge);
  EXPECT_EQ(active_outside, 0);
  EXPECT_GT(active_inside, 2900);
  // Identical plant and model: the estimate moves from 3.391e-3 towards the true 3.45e-3.
  EXPECT_LT(std::abs(last.r_film_est_ohm_m2 - rig.r_true), 0.5 * (rig.r_true - bms::fw::paper::kInitialFilm_ohm_m2));
}

TEST(BmsCore, SaveRestoreContinuesIdentically) {
  Rig rig;
  for (int i = 0; i < 100; ++i) rig.core.tick(rig.sample(2.5));
  for (int i = 0; i < 500; ++i) rig.core.tick(rig.sample(-2.5));
  const auto image = rig.core.save();
  Model model2;
  model2.init(0.5, 0.5, 1000.0);
  Core core2(Core::Config{}, model2);
  ASSERT_TRUE(core2.restore(image));
  for (int i = 0; i < 200; ++i) {
    const auto s = rig.sample(-2.5);
    const auto a = rig.core.tick(s);
    const auto b = core2.tick(s);
    ASSERT_EQ(a.r_film_est_ohm_m2, b.r_film_est_ohm_m2);
    ASSERT_EQ(a.z_v, b.z_v);
  }
  EXPECT_TRUE(same_state(rig.core, core2));
}

TEST(BmsCore, RestoreRejectsForeignOrCorruptImages) {
  Rig rig;
  auto image = rig.core.save();
  image.layout_tag ^= 1u;
  EXPECT_FALSE(rig.core.restore(image));
  EXPECT_TRUE(bms::fw::has_status(rig.core.status(), FwStatus::kRestoreRejected));
  image = rig.core.save();
  image.model.ce_mol_m3[0] = std::nan("");
  const auto before = rig.core.save();
  EXPECT_FALSE(rig.core.restore(image));
  auto now = rig.core.save();
  EXPECT_EQ(std::memcmp(&now.model, &before.model, sizeof(now.model)), 0);
}

TEST(ModeDetector, DebouncesAndFollowsACccvCycle) {
  bms::fw::ModeDetector<double> d;
  auto feed = [&](double v, double i, int n) {
    Mode m = Mode::unknown;
    for (int k = 0; k < n; ++k) m = d.update(v, i);
    return m;
  };
  EXPECT_EQ(feed(3.3, 2.5, 4), Mode::unknown);  // not yet confirmed
  EXPECT_EQ(feed(3.3, 2.5, 1), Mode::cc_discharge);
  // A single noisy sample does not switch.
  EXPECT_EQ(feed(3.3, 0.0, 1), Mode::cc_discharge);
  EXPECT_EQ(feed(3.3, 2.5, 1), Mode::cc_discharge);
  EXPECT_EQ(feed(2.0, 1.0, 5), Mode::cv_discharge);
  EXPECT_EQ(feed(2.3, -2.5, 5), Mode::cc_charge);
  EXPECT_EQ(feed(3.598, -2.5, 5), Mode::cc_charge);  // near the limit but still at the CC level
  EXPECT_EQ(feed(3.6, -1.5, 5), Mode::cv_charge);
  EXPECT_EQ(feed(3.4, 0.0, 5), Mode::rest);
}

TEST(BmsCore, FloatInstantiates) {
  bms::fw::ReducedCell<float> m;
  m.init_default();
  bms::fw::BmsCore<float, bms::fw::ReducedCell<float>, 1, 0> core({}, m);
  const auto out = core.tick({3.3f, 2.5f, true});
  EXPECT_TRUE(std::isfinite(out.r_film_est_ohm_m2));
}

}  // namespace
