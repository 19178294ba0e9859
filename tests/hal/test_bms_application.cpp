// BmsApplication over the fake HAL: the tick's sequence window, bounded lock-step
// triggers, a restarted host, the NVM rollback flag, the NVM fault clearing on recovery, the
// flash write budget and the end-of-charge commit. A small fake core makes every tick's input
// visible; the last tests use the real core and the payload the firmware really saves.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <vector>

#include "bms/fw/estimation/bms_core.hpp"
#include "bms/fw/can/can_protocol.hpp"
#include "bms/fw/config/make_config.hpp"
#include "bms/fw/nvm/state_schema.hpp"
#include "bms/app/bms_application.hpp"
#include "bms/hal/fake/fake_can.hpp"
#include "bms/hal/fake/fake_log.hpp"
#include "bms/hal/fake/fake_nvm.hpp"
#include "bms/hal/fake/fake_time.hpp"
#include "bms/hal/lockstep.hpp"

namespace can = bms::fw::can;
namespace fw = bms::fw;
namespace hal = bms::hal;
using hal::CanFrame;
using hal::Status;
using hal::fake::FakeCanBus;

namespace app_test {

// Records every tick's input; the mode it reports is set by the test.
struct FakeCore {
  struct State {
    double level_v;
    std::uint32_t ticks;
    std::uint32_t missed;
  };
  using Output = fw::TickOutput<double, 1>;

  Output tick(const fw::TickInput<double>& in) {
    inputs.push_back(in);
    ++ticks;
    if (in.present) level_v = in.voltage_v;
    Output o{};
    o.mode = mode;
    o.r_film_est_ohm_m2 = 1e-3;
    o.tick = ticks;
    return o;
  }
  void ticks_missed(std::uint32_t n) { missed += n; }
  State save() const { return State{level_v, ticks, missed}; }
  bool restore(const State& s) {
    if (!std::isfinite(s.level_v)) return false;
    level_v = s.level_v;
    ticks = s.ticks;
    missed = s.missed;
    return true;
  }
  int present() const {
    int n = 0;
    for (const auto& in : inputs) n += in.present ? 1 : 0;
    return n;
  }

  std::vector<fw::TickInput<double>> inputs;
  std::uint32_t ticks = 0;
  std::uint32_t missed = 0;
  double level_v = 0.0;
  fw::Mode mode = fw::Mode::rest;
};

constexpr std::uint32_t state_schema(fw::schema::Type<FakeCore>) {
  using St = FakeCore::State;
  constexpr fw::schema::Field f[] = {BMS_SCHEMA_FIELD(St, level_v), BMS_SCHEMA_FIELD(St, ticks),
                                     BMS_SCHEMA_FIELD(St, missed)};
  return fw::schema::hash("FakeCore.State", f, sizeof(St));
}

}  // namespace app_test

namespace {

using app_test::FakeCore;
using App = bms::app::BmsApplication<FakeCore>;

CanFrame measurement(std::uint8_t counter, std::uint16_t seq, double v) {
  can::Measurement m;
  m.seq = seq;
  m.voltage_v = v;
  m.current_a = -1.0;
  CanFrame f{};
  can::encode(m, counter, f);
  return f;
}

bool classify(const CanFrame& f, std::uint32_t& t, void* c) { return static_cast<can::LockstepTicks*>(c)->classify(f, t); }

// The host side of the bus and a lock-step firmware over fakes.
struct LockstepRig {
  explicit LockstepRig(App::Options o = {}) : app(core, bus, bus, log, nvm, with_rule(o)) {
    FakeCanBus::connect(host, wire);
  }
  App::Options with_rule(App::Options o) {
    o.lockstep = true;
    o.lockstep_ticks = &rule;
    o.tick_timeout_ms = 0;
    return o;
  }
  void send(const CanFrame& f) { ASSERT_EQ(host.send(f), Status::ok); }
  // The host's frame of tick k (seq k, counter k mod 16, 3.0 V + k mV).
  void send_tick(std::uint32_t k) { send(measurement(static_cast<std::uint8_t>(k & 0xF), static_cast<std::uint16_t>(k & 0xFFF), 3.0 + 1e-3 * k)); }
  // Steps until no tick is pending; returns the ticks run.
  int run() {
    int n = 0;
    while (app.step() == Status::ok) ++n;
    return n;
  }
  // The last BMS_Status the firmware sent.
  can::BmsStatus last_status() {
    can::BmsStatus st{};
    CanFrame f{};
    while (host.try_receive(f) == Status::ok) {
      if (f.id == can::id::kStatus) can::decode(f, st);
    }
    return st;
  }

  FakeCanBus host, wire;
  can::LockstepTicks rule;
  hal::LockstepBus<64> bus{wire, classify, &rule};
  hal::fake::RecordingLogSink log;
  hal::fake::RamNvm nvm{8192, 256};
  FakeCore core;
  App app;
};

}  // namespace

TEST(BmsApplication, AnOldFrameWithACounterAheadIsNotUsedAndTheGenuineOneIs) {
  LockstepRig r;
  for (std::uint32_t k = 0; k < 10; ++k) r.send_tick(k);
  ASSERT_EQ(r.run(), 10);
  // An old CRC-valid frame (Seq 5, 9.99 V) whose alive counter is 3 ahead, then the genuine one.
  r.send(measurement((10 + 3) & 0xF, 5, 9.99));
  r.send_tick(10);
  ASSERT_EQ(r.run(), 1);
  ASSERT_TRUE(r.core.inputs.back().present);
  EXPECT_NEAR(r.core.inputs.back().voltage_v, 3.010, 1e-5) << "the genuine frame of tick 10 is used";
  EXPECT_EQ(r.app.receiver().counters().dropped_seq, 1u);
  EXPECT_EQ(r.app.receiver().counters().dropped_counter, 0u);
  EXPECT_EQ(r.core.present(), 11);
}

TEST(BmsApplication, FortyCorruptedCopiesRunOneTickAndStallNoGoodFrame) {
  LockstepRig r;
  for (std::uint32_t k = 0; k <= 10; ++k) r.send_tick(k);
  ASSERT_EQ(r.run(), 11);
  CanFrame bad = measurement(11, 11, 3.011);
  bad.data[4] ^= 0x20;
  for (int c = 0; c < 40; ++c) r.send(bad);
  for (std::uint32_t k = 11; k <= 30; ++k) r.send_tick(k);
  EXPECT_EQ(r.run(), 20) << "tick 11 (on the first corrupted copy) and ticks 12..30";
  EXPECT_EQ(r.core.present(), 11 + 19) << "every good frame after 11 gave its tick its sample";
  EXPECT_EQ(r.app.missed_ticks_total(), 0u);
  EXPECT_EQ(r.rule.last_tick(), 30u);
}

TEST(BmsApplication, AHostRestartingItsSequenceGetsTicksAfterThreeFrames) {
  LockstepRig r;
  for (std::uint32_t k = 1000; k < 1010; ++k) r.send_tick(k);
  ASSERT_EQ(r.run(), 10);
  // The host restarts: Seq and alive counters from 0.
  for (std::uint32_t k = 0; k < 6; ++k) r.send_tick(k);
  EXPECT_EQ(r.run(), 4) << "frames 2, 3, 4, 5 trigger ticks";
  // Frame 2 is the tick's own: its sample is used (its counter, 2, follows the last one, 1009
  // mod 16 = 1); frames 0 and 1 lie outside that tick's window.
  EXPECT_EQ(r.core.present(), 10 + 4);
  EXPECT_EQ(r.app.receiver().counters().dropped_seq, 2u);
  EXPECT_EQ(r.app.missed_ticks_total(), 0u) << "a restart claims no gap";
}

TEST(BmsApplication, OneControlFrameCannotFakeMissedTicks) {
  LockstepRig r;
  for (std::uint32_t k = 0; k < 10; ++k) r.send_tick(k);
  ASSERT_EQ(r.run(), 10);
  can::Transmitter tx;
  can::Control c;
  c.tick_trigger = true;
  c.tick = 9 + 266;
  CanFrame f{};
  tx.encode(c, f);
  r.send(f);
  r.send_tick(10);
  EXPECT_EQ(r.run(), 1);
  EXPECT_EQ(r.app.missed_ticks_total(), 0u) << "before: 265 missed ticks";
  EXPECT_EQ(r.core.missed, 0u);
  // A real gap (frames 11..19 lost) is still accounted for.
  r.send_tick(20);
  EXPECT_EQ(r.run(), 1);
  EXPECT_EQ(r.core.missed, 9u);
}

TEST(BmsApplication, EndOfChargeCommitsAndTheTimerIsBounded) {
  App::Options o;
  o.persist_every_ticks = 0;
  LockstepRig r(o);
  r.core.mode = fw::Mode::cc_charge;
  for (std::uint32_t k = 0; k < 5; ++k) r.send_tick(k);
  ASSERT_EQ(r.run(), 5);
  EXPECT_EQ(r.app.nvm_counters().commits, 0u);
  r.core.mode = fw::Mode::cv_charge;
  r.send_tick(5);
  ASSERT_EQ(r.run(), 1);
  EXPECT_EQ(r.app.nvm_counters().commits, 1u) << "the end of the CC charge is committed";
}

TEST(BmsApplication, TheWriteBudgetBoundsCommitsAndFlashWear) {
  App::Options o;
  o.persist_every_ticks = 1;  // asks for a commit every tick
  o.budget.endurance_cycles = 100.0;
  o.budget.burst_commits = 2;
  o.budget.tick_s = 0.2;
  o.budget.lifetime_s = 10.0 * 0.2 * (2.0 * 100.0 - 2.0);  // interval: 10 ticks
  LockstepRig r(o);
  ASSERT_EQ(r.app.write_budget().interval_ticks(), 10u);
  constexpr std::uint32_t kTicks = 300;
  for (std::uint32_t k = 0; k < kTicks; ++k) r.send_tick(k);
  ASSERT_EQ(r.run(), static_cast<int>(kTicks));
  const std::uint32_t commits = r.app.nvm_counters().commits;
  EXPECT_LE(commits, 2u + kTicks / 10u);
  EXPECT_GE(commits, kTicks / 10u);
  EXPECT_EQ(r.nvm.erases(), commits) << "one erase per commit: the wear the budget bounds";
  // The worked figure of nvm_budget.hpp: 10 000 cycles over 10 years at 0.2 s ticks.
  EXPECT_EQ(fw::nvm::WriteBudget::interval_for(fw::nvm::WriteBudgetConfig{}), 78910u);
  fw::nvm::WriteBudgetConfig per_minute;
  per_minute.lifetime_s = 2.0 * 10000.0 * 60.0;
  EXPECT_EQ(fw::nvm::WriteBudget::interval_for(per_minute), 301u) << "13.9 days at one commit per 60 s";
}

TEST(BmsApplication, RollbackToTheOlderSlotIsFlaggedAndTheNvmFaultClearsOnRecovery) {
  hal::fake::RamNvm nvm(8192, 256);
  {
    LockstepRig r;
    for (std::uint32_t k = 0; k < 3; ++k) r.send_tick(k);
    ASSERT_EQ(r.run(), 3);
    ASSERT_TRUE(r.app.persist());
    r.send_tick(3);
    ASSERT_EQ(r.run(), 1);
    ASSERT_TRUE(r.app.persist());
    const int newest = r.app.store().newest_slot();
    // Corrupt the newer record's CRC (its last 4 bytes): as a commit torn by a power cut.
    const std::size_t crc_at = r.app.store().slot_offset(newest) + App::Store::kRecordBytes - 4;
    std::uint8_t zeros[4] = {0, 0, 0, 0};
    ASSERT_EQ(r.nvm.write(crc_at, zeros, 4), Status::ok);
    nvm = r.nvm;
  }
  LockstepRig r;
  r.nvm = nvm;
  ASSERT_TRUE(r.app.restore_from_nvm());
  EXPECT_TRUE(r.app.rolled_back());
  EXPECT_NEAR(r.core.level_v, 3.002, 1e-9) << "the older state (after tick 2)";
  r.send_tick(4);
  ASSERT_EQ(r.run(), 1);
  can::BmsStatus st = r.last_status();
  EXPECT_TRUE(st.status_bits & can::status_bit::kNvmRolledBack);
  EXPECT_TRUE(st.fault_bits & can::fault_bit::kNvm);
  ASSERT_TRUE(r.app.persist());
  r.send_tick(5);
  ASSERT_EQ(r.run(), 1);
  st = r.last_status();
  EXPECT_FALSE(st.fault_bits & can::fault_bit::kNvm) << "a good commit clears the NVM fault";
  EXPECT_TRUE(st.status_bits & can::status_bit::kNvmRolledBack) << "what start-up did stays reported";
  // A failed commit sets it again, the next good one clears it again.
  r.nvm.fail_next_erase();
  EXPECT_FALSE(r.app.persist());
  r.send_tick(6);
  ASSERT_EQ(r.run(), 1);
  EXPECT_TRUE(r.last_status().fault_bits & can::fault_bit::kNvm);
  ASSERT_TRUE(r.app.persist());
  r.send_tick(7);
  ASSERT_EQ(r.run(), 1);
  EXPECT_FALSE(r.last_status().fault_bits & can::fault_bit::kNvm);
}

TEST(BmsApplication, RealTimeWindowDropsReplaysAndFollowsARestartedHost) {
  FakeCanBus host, wire;
  FakeCanBus::connect(host, wire);
  hal::fake::ManualTickSource ticks;
  hal::fake::RecordingLogSink log;
  hal::fake::RamNvm nvm(8192, 256);
  FakeCore core;
  App::Options o;
  o.lockstep = false;
  App app(core, wire, ticks, log, nvm, o);
  auto tick_with = [&](std::initializer_list<CanFrame> frames) {
    for (const CanFrame& f : frames) host.send(f);
    ticks.fire();
    EXPECT_EQ(app.step(), Status::ok);
    return core.inputs.back();
  };
  for (std::uint16_t s = 100; s < 105; ++s)
    EXPECT_TRUE(tick_with({measurement(static_cast<std::uint8_t>(s & 0xF), s, 3.0 + 1e-3 * (s - 100))}).present);
  // A replay of Seq 50 with a counter 3 ahead, then the genuine 105.
  const auto in = tick_with({measurement((105 + 3) & 0xF, 50, 9.99), measurement(105 & 0xF, 105, 3.005)});
  ASSERT_TRUE(in.present);
  EXPECT_NEAR(in.voltage_v, 3.005, 1e-5);
  // A tick without a frame, then two in one tick (clock jitter): both inside the window.
  EXPECT_FALSE(tick_with({}).present);
  EXPECT_TRUE(tick_with({measurement(106 & 0xF, 106, 3.006), measurement(107 & 0xF, 107, 3.007)}).present);
  // The firmware was late by 5 ticks (a stalled process; the timer skips them) and the host's
  // frames of those ticks were lost: its next Seq is 6 ahead, and the window counts the
  // skipped ticks (the alive counter's step, 6, is within its own limit of 7).
  ticks.overrun(5);
  const auto late = tick_with({measurement((108 + 5) & 0xF, 108 + 5, 3.113)});
  EXPECT_TRUE(late.present);
  EXPECT_EQ(app.missed_ticks_total(), 5u);
  // The host restarts at Seq 0 (counters from 0): followed after three frames.
  int first_present = -1;
  for (std::uint16_t s = 0; s < 8; ++s) {
    if (tick_with({measurement(static_cast<std::uint8_t>(s), s, 3.1)}).present && first_present < 0) first_present = s;
  }
  EXPECT_GE(first_present, 3);
  EXPECT_LE(first_present, 4);
}

// ---------------------------------------------------------------- the real core and payload

namespace {

using Model = fw::ReducedCell<double>;
using Core = fw::BmsCore<double, Model, 1, 0>;
using RealApp = bms::app::BmsApplication<Core>;

// The firmware's core driven through a CC charge by a second model (the plant): a state
// with everything in use, as the firmware saves it.
struct RealRig {
  RealRig() : core(fw::paper_cell_config<Core>(fw::Profile::best), model) {
    model.init_default();
    plant.init_default();
  }
  void run(int ticks, double current_a) {
    for (int k = 0; k < ticks; ++k) {
      const auto p = plant.step_current(current_a, fw::PaperCellTraits::kInitialFilmOhmM2, 0.2);
      core.tick({p.voltage_v, current_a, true});
    }
  }
  RealApp::Persisted persisted(std::uint32_t tick) const {
    RealApp::Persisted p{};
    p.core = core.save();
    p.tick = tick;
    p.budget_credit_ticks = 7;
    return p;
  }
  Model model, plant;
  Core core;
};

}  // namespace

TEST(NvmRestore, EveryScalarFieldIsRangeChecked) {
  RealRig rig;
  rig.run(50, -2.5);
  const Core::State good = rig.core.save();
  Model m2;
  m2.init_default();
  Core fresh(fw::paper_cell_config<Core>(fw::Profile::best), m2);
  ASSERT_TRUE(fresh.restore(good));
  // The case: a lithium loss of 1e308 (finite) made every output infinite.
  Core::State s = good;
  s.model.li_loss_mol = 1e308;
  EXPECT_FALSE(fresh.restore(s));
  struct Bad {
    const char* field;
    void (*apply)(Core::State&);
  };
  const Bad cases[] = {
      {"model.cs_neg", [](Core::State& x) { x.model.cs_neg_mol_m3[0] = -1e9; }},
      {"model.cs_pos", [](Core::State& x) { x.model.cs_pos_mol_m3[0] = 1e9; }},
      {"model.ce", [](Core::State& x) { x.model.ce_mol_m3[0] = 1e7; }},
      {"model.charge_c", [](Core::State& x) { x.model.charge_c = 1e300; }},
      {"model.current_a", [](Core::State& x) { x.model.current_a = 1e6; }},
      {"bias_v", [](Core::State& x) { x.bias.bias_v = 5.0; }},
      {"r_held", [](Core::State& x) { x.film.r_held_ohm_m2 = 1e200; }},
      {"growth", [](Core::State& x) { x.film.growth_ohm_m2 = -1e100; }},
      {"last_current_a", [](Core::State& x) { x.last_current_a = 1e200; }},
      {"inventory_deviation", [](Core::State& x) { x.resync.inventory_deviation_model = 0.9; }},
      {"identifier.growth", [](Core::State& x) { x.identifier.growth_ohm_m2 = 1e250; }},
  };
  for (const Bad& b : cases) {
    Core::State x = good;
    b.apply(x);
    EXPECT_FALSE(fresh.restore(x)) << b.field;
  }
  EXPECT_TRUE(fresh.restore(good)) << "a rejected image changed nothing";
}

TEST(NvmRestore, TheLayoutTagIsASchemaHash) {
  // Same sizes, fields swapped or retyped: the old size-only tag could not tell them apart.
  struct A {
    double x_v;
    double y_a;
  };
  struct B {
    double y_a;
    double x_v;
  };
  struct C {
    double x_v;
    std::int64_t y_a;
  };
  using fw::schema::Field;
  constexpr Field fa[] = {BMS_SCHEMA_FIELD(A, x_v), BMS_SCHEMA_FIELD(A, y_a)};
  constexpr Field fb[] = {BMS_SCHEMA_FIELD(B, y_a), BMS_SCHEMA_FIELD(B, x_v)};
  constexpr Field fc[] = {BMS_SCHEMA_FIELD(C, x_v), BMS_SCHEMA_FIELD(C, y_a)};
  static_assert(fw::schema::hash("S", fa, sizeof(A)) != fw::schema::hash("S", fb, sizeof(B)), "order");
  static_assert(fw::schema::hash("S", fa, sizeof(A)) != fw::schema::hash("S", fc, sizeof(C)), "type");
  // An undescribed field makes covers() false (a static_assert in state_schema.hpp).
  struct D {
    double x_v;
    double y_a;
    double z;
  };
  constexpr Field fd[] = {BMS_SCHEMA_FIELD(D, x_v), BMS_SCHEMA_FIELD(D, y_a)};
  static_assert(!fw::schema::covers(fd, sizeof(D), alignof(D)), "a field missing from the table");
  static_assert(fw::schema::covers(fa, sizeof(A), alignof(A)), "complete");
  // The firmware's tag is the schema hash, and it differs between the float and double cores.
  using FloatCore = fw::BmsCore<float, fw::ReducedCell<float>, 1, 0>;
  EXPECT_NE(RealApp::kPersistedTag, bms::app::BmsApplication<FloatCore>::kPersistedTag);
  EXPECT_NE(fw::schema::state_schema_hash<Core>(), 0u);
}

// The power-cut sweep of tests/hal/test_nvm_store.cpp, on what the firmware really commits
// (BmsApplication::Persisted of the real core): a cut at every byte of two commits loads the
// last committed payload, whose restore succeeds and whose next tick is finite.
TEST(NvmRestore, PowerCutAtEveryByteOfTheRealPayload) {
  using Store = fw::nvm::RecordStore<RealApp::Persisted, RealApp::kPersistedTag, hal::fake::RamNvm>;
  RealRig rig;
  rig.run(100, 1.0);
  const RealApp::Persisted first = rig.persisted(100);
  rig.run(100, -2.5);
  const RealApp::Persisted second = rig.persisted(200);
  hal::fake::RamNvm device(8192, 256);
  ASSERT_EQ(Store(device, 0).save(first), fw::nvm::StoreStatus::ok);
  static RealApp::Persisted out;  // large: not on the stack
  int cuts = 0, bad = 0;
  for (std::size_t n = 0; n <= Store::kRecordBytes; ++n) {
    hal::fake::RamNvm ram = device;
    ram.tear_next_write_at(n);
    ASSERT_EQ(Store(ram, 0).save(second), fw::nvm::StoreStatus::io_error);
    ++cuts;
    Store rebooted(ram, 0);
    ASSERT_EQ(rebooted.load(out), fw::nvm::StoreStatus::ok) << n;
    const bool is_first = std::memcmp(&out, &first, sizeof out) == 0;
    const bool is_second = n == Store::kRecordBytes && std::memcmp(&out, &second, sizeof out) == 0;
    if (!is_first && !is_second) ++bad;
    if (n > 0 && n < Store::kRecordBytes) {
      EXPECT_TRUE(rebooted.fell_back()) << n;
    }
  }
  EXPECT_EQ(bad, 0);
  Model m2;
  m2.init_default();
  Core restored(fw::paper_cell_config<Core>(fw::Profile::best), m2);
  ASSERT_TRUE(restored.restore(out.core));
  const auto o = restored.tick({3.4, -2.5, true});
  EXPECT_TRUE(std::isfinite(o.r_film_est_ohm_m2) && std::isfinite(o.li_loss_ah) && std::isfinite(o.z_v));
  std::printf("[nvm power-cut, real payload] record %zu bytes, %d cut points, bad loads %d\n", Store::kRecordBytes,
              cuts, bad);
}
