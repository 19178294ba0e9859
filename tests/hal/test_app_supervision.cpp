// The application's supervision and host commands over the fake HAL: the watchdog
// kicked once per completed tick, the tick-overrun fault bit from the tick's measured
// duration, the internal fault bit on a failed send, ResetEstimator, HOST_Temperature, and
// the end-of-charge commit restored into a fresh application.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>

#include "bms/app/bms_application.hpp"
#include "bms/fw/can/can_protocol.hpp"
#include "bms/fw/nvm/state_schema.hpp"
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

namespace supervision_test {

// A core whose tick takes the time the test says (on the fake clock) and whose state is the
// last voltage and the tick count.
struct TimedCore {
  struct State {
    double level_v;
    std::uint32_t ticks;
  };
  using Output = fw::TickOutput<double, 1>;

  Output tick(const fw::TickInput<double>& in) {
    if (clock != nullptr) clock->advance_ns(cost_ns);
    ++ticks;
    if (in.present) level_v = in.voltage_v;
    Output o{};
    o.mode = mode;
    o.r_film_est_ohm_m2 = 1e-3;
    o.status = status;
    // As BmsCore with the reduced model: a temperature outside the model's range is refused.
    if (in.present && in.temperature_k != 0.0) {
      using Model = fw::ReducedCell<double>;
      if (in.temperature_k >= Model::kMinTemperatureK && in.temperature_k <= Model::kMaxTemperatureK) {
        temperature_k = in.temperature_k;
      } else {
        o.status |= fw::bit(fw::FwStatus::kTemperatureImplausible);
      }
    }
    o.tick = ticks;
    return o;
  }
  void ticks_missed(std::uint32_t) {}
  State save() const { return State{level_v, ticks}; }
  bool restore(const State& s) {
    if (!std::isfinite(s.level_v)) return false;
    level_v = s.level_v;
    ticks = s.ticks;
    return true;
  }

  hal::fake::ManualClock* clock = nullptr;
  std::uint64_t cost_ns = 0;
  double level_v = 0.0;
  double temperature_k = 0.0;  // the last accepted temperature
  std::uint32_t ticks = 0;
  fw::Mode mode = fw::Mode::rest;
  fw::StatusWord status = 0;
};

constexpr std::uint32_t state_schema(fw::schema::Type<TimedCore>) {
  using St = TimedCore::State;
  constexpr fw::schema::Field f[] = {BMS_SCHEMA_FIELD(St, level_v), BMS_SCHEMA_FIELD(St, ticks)};
  return fw::schema::hash("TimedCore.State", f, sizeof(St));
}

}  // namespace supervision_test

namespace {

using supervision_test::TimedCore;
using App = bms::app::BmsApplication<TimedCore>;
constexpr std::uint64_t kMs = 1000000u;

bool classify(const CanFrame& f, std::uint32_t& t, void* c) { return static_cast<can::LockstepTicks*>(c)->classify(f, t); }

// A lock-step firmware over fakes with a counting watchdog and a manual clock.
struct Rig {
  explicit Rig(App::Options o = {}) : app(core, bus, bus, log, nvm, with_rig(o)) {
    FakeCanBus::connect(host, wire);
    core.clock = &clock;
  }
  App::Options with_rig(App::Options o) {
    o.lockstep = true;
    o.lockstep_ticks = &rule;
    o.tick_timeout_ms = 0;
    o.watchdog = &watchdog;
    o.clock = &clock;
    return o;
  }
  template <class M>
  void send(const M& m) {
    CanFrame f{};
    host_tx.encode(m, f);
    ASSERT_EQ(host.send(f), Status::ok);
  }
  void send_tick(std::uint32_t k) {
    can::Measurement m;
    m.seq = static_cast<std::uint16_t>(k & 0xFFF);
    m.voltage_v = 3.0 + 1e-3 * k;
    m.current_a = -1.0;
    send(m);
  }
  int run() {
    int n = 0;
    while (app.step() == Status::ok) ++n;
    return n;
  }
  // The BMS_Status frames the firmware sent since the last call, in order.
  std::vector<can::BmsStatus> statuses() {
    std::vector<can::BmsStatus> out;
    CanFrame f{};
    while (host.try_receive(f) == Status::ok) {
      can::BmsStatus st{};
      if (f.id == can::id::kStatus && can::decode(f, st)) out.push_back(st);
    }
    return out;
  }

  FakeCanBus host, wire;
  can::Transmitter host_tx;
  can::LockstepTicks rule;
  hal::LockstepBus<64> bus{wire, classify, &rule};
  hal::fake::RecordingLogSink log;
  hal::fake::RamNvm nvm{8192, 256};
  hal::fake::ManualClock clock;
  hal::fake::CountingWatchdog watchdog;
  TimedCore core;
  App app;
};

TEST(AppSupervision, TheWatchdogIsKickedOncePerCompletedTickAndNotWhileWaiting) {
  Rig r;
  for (std::uint32_t k = 0; k < 7; ++k) r.send_tick(k);
  ASSERT_EQ(r.run(), 7);
  EXPECT_EQ(r.watchdog.kicks(), 7u);
  EXPECT_EQ(r.app.step(), Status::timeout) << "no frame, no tick";
  EXPECT_EQ(r.watchdog.kicks(), 7u) << "a tick that did not come is not kicked for";
}

TEST(AppSupervision, ATickOverItsBudgetSetsTheOverrunBitForThatTickAndIsCounted) {
  App::Options o;
  o.tick_budget_ns = 100 * kMs;
  Rig r(o);
  const std::uint64_t costs_ms[] = {20, 99, 150, 20, 300, 20};
  for (std::uint32_t k = 0; k < 6; ++k) {
    r.core.cost_ns = costs_ms[k] * kMs;
    r.send_tick(k);
    ASSERT_EQ(r.run(), 1);
  }
  const std::vector<can::BmsStatus> st = r.statuses();
  ASSERT_EQ(st.size(), 6u);
  for (std::size_t k = 0; k < 6; ++k) {
    const bool over = costs_ms[k] > 100;
    EXPECT_EQ((st[k].fault_bits & can::fault_bit::kTickOverrun) != 0, over) << "tick " << k;
  }
  EXPECT_EQ(r.app.supervisor().overruns(), 2u);
  EXPECT_EQ(r.app.supervisor().worst_tick_ns(), 300 * kMs);
  EXPECT_EQ(r.watchdog.kicks(), 6u) << "an overrunning tick still completes and kicks";
}

TEST(AppSupervision, TheDefaultBudgetIsTheTickPeriod) {
  Rig r;
  EXPECT_EQ(r.app.supervisor().budget_ns(), hal::kTickPeriodNs);
  r.core.cost_ns = hal::kTickPeriodNs + 1u;
  r.send_tick(0);
  ASSERT_EQ(r.run(), 1);
  EXPECT_NE(r.statuses().back().fault_bits & can::fault_bit::kTickOverrun, 0);
}

TEST(AppSupervision, RealTimeTicksSkippedByTheTimerAreAnOverrun) {
  FakeCanBus bus;
  FakeCanBus::connect(bus, bus);
  hal::fake::ManualTickSource ticks;
  hal::fake::RecordingLogSink log;
  hal::fake::RamNvm nvm{8192, 256};
  TimedCore core;
  App::Options o;
  o.lockstep = false;
  o.tick_timeout_ms = 0;
  App app(core, bus, ticks, log, nvm, o);
  ticks.fire(2);
  ASSERT_EQ(app.step(), Status::ok);
  ASSERT_EQ(app.step(), Status::ok);
  EXPECT_EQ(app.last_status_fault_bits() & can::fault_bit::kTickOverrun, 0);
  ticks.overrun(3);
  ticks.fire();
  ASSERT_EQ(app.step(), Status::ok);
  EXPECT_NE(app.last_status_fault_bits() & can::fault_bit::kTickOverrun, 0);
  EXPECT_EQ(app.missed_ticks_total(), 3u);
}

TEST(AppSupervision, CallOrderOrConfigFaultsOfTheCoreAndFailedSendsAreInternalFaults) {
  Rig r;
  r.send_tick(0);
  ASSERT_EQ(r.run(), 1);
  EXPECT_EQ(r.statuses().back().fault_bits & can::fault_bit::kInternal, 0);
  r.core.status = fw::bit(fw::FwStatus::kCallOrder);
  r.send_tick(1);
  ASSERT_EQ(r.run(), 1);
  EXPECT_NE(r.statuses().back().fault_bits & can::fault_bit::kInternal, 0);
  r.core.status = fw::bit(fw::FwStatus::kModelInvalid);
  r.send_tick(2);
  ASSERT_EQ(r.run(), 1);
  const std::uint8_t f = r.statuses().back().fault_bits;
  EXPECT_EQ(f & can::fault_bit::kInternal, 0) << "a non-finite model state is the estimator's fault";
  EXPECT_NE(f & can::fault_bit::kEstimator, 0);
  // The estimate frames of tick 3 cannot be sent: the Status after them reports it.
  r.core.status = 0;
  r.wire.set_send_status(Status::io_error);
  r.send_tick(3);
  ASSERT_EQ(r.run(), 1);
  EXPECT_EQ(r.app.send_failures(), 7u);  // all seven frames of the tick, BMS_Status included
  r.wire.set_send_status(Status::ok);
  r.send_tick(4);
  ASSERT_EQ(r.run(), 1);
  EXPECT_NE(r.app.last_status_fault_bits() & can::fault_bit::kInternal, 0) << "reported once the bus is back";
  r.send_tick(5);
  ASSERT_EQ(r.run(), 1);
  EXPECT_EQ(r.app.last_status_fault_bits() & can::fault_bit::kInternal, 0);
}

TEST(AppSupervision, ResetEstimatorGoesBackToThePowerOnStateAndCommitsIt) {
  App::Options o;
  o.persist_every_ticks = 0;
  Rig r(o);
  for (std::uint32_t k = 0; k < 4; ++k) r.send_tick(k);
  ASSERT_EQ(r.run(), 4);
  ASSERT_TRUE(r.app.persist());
  ASSERT_NEAR(r.core.level_v, 3.003, 1e-12);
  can::Control c;
  c.reset_estimator = true;
  r.send(c);
  r.send_tick(4);
  ASSERT_EQ(r.run(), 1);
  EXPECT_EQ(r.app.resets(), 1u);
  EXPECT_EQ(r.core.ticks, 1u) << "the tick after the reset runs from the power-on state";
  EXPECT_EQ(r.app.nvm_counters().commits, 2u) << "the reset state is committed";
  // A power cycle brings the reset state back, not the one learned before it.
  Rig fresh;
  fresh.nvm = r.nvm;
  ASSERT_TRUE(fresh.app.restore_from_nvm());
  EXPECT_EQ(fresh.core.ticks, 1u);
  // A Control frame without the bit resets nothing.
  c.reset_estimator = false;
  r.send(c);
  r.send_tick(5);
  ASSERT_EQ(r.run(), 1);
  EXPECT_EQ(r.app.resets(), 1u);
  EXPECT_EQ(r.core.ticks, 2u);
}

TEST(AppSupervision, AControlFrameClaimingTheOtherClockIsAnInternalFault) {
  Rig r;  // lock-step
  can::Control c;
  c.lockstep = true;
  r.send(c);
  r.send_tick(0);
  ASSERT_EQ(r.run(), 1);
  EXPECT_EQ(r.statuses().back().fault_bits & can::fault_bit::kInternal, 0);
  c.lockstep = false;  // the host thinks the firmware's timer drives the ticks
  r.send(c);
  r.send_tick(1);
  ASSERT_EQ(r.run(), 1);
  EXPECT_NE(r.statuses().back().fault_bits & can::fault_bit::kInternal, 0);
  EXPECT_EQ(r.app.clock_mismatches(), 1u);
  r.send_tick(2);  // reported once, in the tick that saw it
  ASSERT_EQ(r.run(), 1);
  EXPECT_EQ(r.statuses().back().fault_bits & can::fault_bit::kInternal, 0);
}

TEST(AppSupervision, ACellOutsideTheModelsTemperatureMakesTheEstimateNotValid) {
  Rig r;
  r.send_tick(0);
  ASSERT_EQ(r.run(), 1);
  EXPECT_NE(r.statuses().back().status_bits & can::status_bit::kEstimateValid, 0);
  can::Temperature t;
  t.temperature_k = 373.15;  // beyond the model's range (ReducedCell::kMaxTemperatureK)
  r.send(t);
  r.send_tick(1);
  ASSERT_EQ(r.run(), 1);
  can::BmsStatus st = r.statuses().back();
  EXPECT_EQ(st.status_bits & can::status_bit::kEstimateValid, 0);
  EXPECT_NE(st.fault_bits & can::fault_bit::kEstimator, 0);
  t.temperature_k = 318.15;  // 20 K from the reference: the model follows it
  r.send(t);
  r.send_tick(2);
  ASSERT_EQ(r.run(), 1);
  st = r.statuses().back();
  EXPECT_NE(st.status_bits & can::status_bit::kEstimateValid, 0);
  EXPECT_EQ(st.fault_bits & can::fault_bit::kEstimator, 0);
  EXPECT_NEAR(r.core.temperature_k, 318.15, 0.01);  // the frame carries it to 0.01 K
}

TEST(AppSupervision, TheEndOfChargeCommitIsRestoredIntoAFreshApplication) {
  App::Options o;
  o.persist_every_ticks = 0;
  Rig r(o);
  r.core.mode = fw::Mode::cc_charge;
  for (std::uint32_t k = 0; k < 3; ++k) r.send_tick(k);
  ASSERT_EQ(r.run(), 3);
  r.core.mode = fw::Mode::rest;
  r.send_tick(3);
  ASSERT_EQ(r.run(), 1);
  ASSERT_EQ(r.app.nvm_counters().commits, 1u);
  Rig fresh(o);
  fresh.nvm = r.nvm;
  ASSERT_TRUE(fresh.app.restore_from_nvm());
  EXPECT_TRUE(fresh.app.restored());
  EXPECT_NEAR(fresh.core.level_v, 3.003, 1e-12);
  EXPECT_EQ(fresh.core.ticks, 4u);
  EXPECT_EQ(fresh.app.last_tick(), 3u);
}

}  // namespace
