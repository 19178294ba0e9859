// The test fakes themselves (torn NVM writes, CAN fault injection, manual time), the
// lock-step bus, and an end-to-end run host -> faulty bus -> receiver.
#include <gtest/gtest.h>

#include <cstring>
#include <vector>

#include "bms/fw/can/can_protocol.hpp"
#include "bms/hal/fake/fake_can.hpp"
#include "bms/hal/fake/fake_log.hpp"
#include "bms/hal/fake/fake_nvm.hpp"
#include "bms/hal/fake/fake_time.hpp"
#include "bms/hal/hal.hpp"

namespace can = bms::fw::can;
namespace hal = bms::hal;
using hal::CanFrame;
using hal::Status;
using hal::fake::FakeCanBus;

namespace {

CanFrame frame(std::uint32_t id, std::uint8_t len = 8, std::uint8_t fill = 0) {
  CanFrame f{};
  f.id = id;
  f.len = len;
  std::memset(f.data, fill, sizeof f.data);
  return f;
}

CanFrame measurement_frame(std::uint8_t counter, std::uint16_t seq) {
  can::Measurement m;
  m.seq = seq;
  m.voltage_v = 3.4;
  m.current_a = -2.5;
  CanFrame f{};
  can::encode(m, counter, f);
  return f;
}

}  // namespace

// ---------------------------------------------------------------- NVM

TEST(RamNvm, StartsErasedAndReadsBackWrites) {
  hal::fake::RamNvm nvm(1024, 256);
  EXPECT_EQ(nvm.size_bytes(), 1024u);
  EXPECT_EQ(nvm.page_size(), 256u);
  std::uint8_t buf[16];
  ASSERT_EQ(nvm.read(1000, buf, 16), Status::ok);
  for (auto b : buf) EXPECT_EQ(b, hal::kNvmErasedByte);
  const char msg[] = "film=3.391e-3";
  ASSERT_EQ(nvm.write(100, msg, sizeof msg), Status::ok);
  char back[sizeof msg];
  ASSERT_EQ(nvm.read(100, back, sizeof back), Status::ok);
  EXPECT_STREQ(back, msg);
  EXPECT_EQ(nvm.read(1020, buf, 5), Status::out_of_range);
  EXPECT_EQ(nvm.write(1024, msg, 1), Status::out_of_range);
  EXPECT_EQ(nvm.write(static_cast<std::size_t>(-1), msg, 2), Status::out_of_range);
  EXPECT_EQ(nvm.erase(100, 256), Status::invalid_argument);
  EXPECT_EQ(nvm.erase(0, 100), Status::invalid_argument);
  EXPECT_EQ(nvm.erase(768, 512), Status::out_of_range);
  ASSERT_EQ(nvm.erase(0, 256), Status::ok);
  ASSERT_EQ(nvm.read(100, back, sizeof back), Status::ok);
  for (char ch : back) EXPECT_EQ(static_cast<std::uint8_t>(ch), 0xFF);
}

TEST(RamNvm, TornWriteLandsOnlyThePrefix) {
  hal::fake::RamNvm nvm(512, 128);
  std::uint8_t old_data[32];
  std::uint8_t new_data[32];
  for (int i = 0; i < 32; ++i) {
    old_data[i] = static_cast<std::uint8_t>(i);
    new_data[i] = static_cast<std::uint8_t>(0xA0 + i);
  }
  ASSERT_EQ(nvm.write(64, old_data, 32), Status::ok);
  nvm.tear_next_write_at(11);
  EXPECT_EQ(nvm.write(64, new_data, 32), Status::io_error);
  EXPECT_NE(std::string(nvm.last_error()).find("power loss"), std::string::npos);
  EXPECT_EQ(nvm.torn_writes(), 1u);
  std::uint8_t got[32];
  ASSERT_EQ(nvm.read(64, got, 32), Status::ok);
  for (int i = 0; i < 32; ++i) EXPECT_EQ(got[i], i < 11 ? new_data[i] : old_data[i]) << i;
  // Only the next write is torn.
  ASSERT_EQ(nvm.write(64, new_data, 32), Status::ok);
  ASSERT_EQ(nvm.read(64, got, 32), Status::ok);
  EXPECT_EQ(std::memcmp(got, new_data, 32), 0);
  // Torn at 0: nothing lands.
  nvm.tear_next_write_at(0);
  EXPECT_EQ(nvm.write(64, old_data, 32), Status::io_error);
  ASSERT_EQ(nvm.read(64, got, 32), Status::ok);
  EXPECT_EQ(std::memcmp(got, new_data, 32), 0);
  // Erase failure leaves the data.
  nvm.fail_next_erase();
  EXPECT_EQ(nvm.erase(0, 128), Status::io_error);
  ASSERT_EQ(nvm.read(64, got, 32), Status::ok);
  EXPECT_EQ(std::memcmp(got, new_data, 32), 0);
  EXPECT_EQ(nvm.writes(), 4u);
}

// ---------------------------------------------------------------- CAN

TEST(FakeCan, PairDeliversBothWaysAndLoopbackToSelf) {
  FakeCanBus a, b;
  FakeCanBus::connect(a, b);
  ASSERT_EQ(a.send(frame(0x110, 8, 1)), Status::ok);
  ASSERT_EQ(b.send(frame(0x200, 4, 2)), Status::ok);
  CanFrame f{};
  ASSERT_EQ(b.receive(f, 0), Status::ok);
  EXPECT_EQ(f.id, 0x110u);
  EXPECT_EQ(f.len, 8);
  EXPECT_EQ(b.try_receive(f), Status::timeout);
  ASSERT_EQ(a.receive(f, hal::kCanWaitForever), Status::ok);
  EXPECT_EQ(f.id, 0x200u);
  EXPECT_EQ(f.data[0], 2);
  EXPECT_EQ(a.sent().size(), 1u);

  FakeCanBus loop;
  FakeCanBus::connect(loop, loop);
  ASSERT_EQ(loop.send(frame(0x7FF, 0)), Status::ok);
  ASSERT_EQ(loop.try_receive(f), Status::ok);
  EXPECT_EQ(f.id, 0x7FFu);
  EXPECT_EQ(f.len, 0);
}

TEST(FakeCan, RejectsInvalidFrames) {
  FakeCanBus a;
  EXPECT_EQ(a.send(frame(0x800)), Status::invalid_argument);
  EXPECT_EQ(a.send(frame(0x100, 9)), Status::invalid_argument);
  EXPECT_EQ(a.send(frame(0x1FFFFFFFu | hal::kCanIdExtended)), Status::ok);
}

TEST(FakeCan, FiltersLikeSocketCan) {
  FakeCanBus a, b;
  FakeCanBus::connect(a, b);
  const hal::CanFilter filters[] = {hal::can_filter_exact(0x110), {0x200, 0x7F0}};
  ASSERT_EQ(b.set_filters(filters, 2), Status::ok);
  for (std::uint32_t id : {0x100u, 0x110u, 0x111u, 0x200u, 0x20Fu, 0x210u}) a.send(frame(id));
  std::vector<std::uint32_t> got;
  CanFrame f{};
  while (b.try_receive(f) == Status::ok) got.push_back(f.id);
  EXPECT_EQ(got, (std::vector<std::uint32_t>{0x110u, 0x200u, 0x20Fu}));
  EXPECT_EQ(b.filtered_out(), 3u);
  ASSERT_EQ(b.set_filters(nullptr, 0), Status::ok);  // nothing
  a.send(frame(0x110));
  EXPECT_EQ(b.try_receive(f), Status::timeout);
  hal::CanFilter many[hal::kCanMaxFilters + 1] = {};
  EXPECT_EQ(b.set_filters(many, hal::kCanMaxFilters + 1), Status::invalid_argument);
}

TEST(FakeCan, FaultInjectionReachesTheReceiverAsDrops) {
  FakeCanBus host, bms;
  FakeCanBus::connect(host, bms);
  can::Transmitter tx;
  can::Receiver rx;
  can::RxMessage msg;
  auto send_meas = [&](std::uint16_t seq) {
    can::Measurement m;
    m.seq = seq;
    m.voltage_v = 3.3;
    CanFrame f{};
    tx.encode(m, f);
    return host.send(f);
  };
  auto drain = [&]() {
    CanFrame f{};
    while (bms.try_receive(f) == Status::ok) rx.accept(f, msg);
  };
  send_meas(0);                // ok
  host.corrupt_next(5, 0x10);  // bit error
  send_meas(1);
  host.truncate_next(5);  // DLC error
  send_meas(2);
  host.duplicate_next();  // repeated counter
  send_meas(3);
  host.drop_next(2);  // lost on the wire
  send_meas(4);
  send_meas(5);
  send_meas(6);
  drain();
  EXPECT_EQ(rx.counters().accepted, 3u);  // seq 0, 3, 6
  EXPECT_EQ(rx.counters().dropped_crc, 1u);
  EXPECT_EQ(rx.counters().dropped_length, 1u);
  EXPECT_EQ(rx.counters().dropped_counter, 1u);
  EXPECT_EQ(rx.counters().lost_frames, 2u + 2u);  // 1,2 (dropped) and 4,5 (lost)
  EXPECT_EQ(msg.measurement.seq, 6);
  EXPECT_EQ(host.sent().size(), 7u);

  // A hook: freeze the alive counter of every frame from now on.
  host.set_fault_hook([](CanFrame& f) {
    f.data[1] = static_cast<std::uint8_t>(f.data[1] & 0xF0u);
    f.data[0] = can::frame_crc(f.id, f.data, f.len);  // a sender with a valid CRC but stuck counter
    return hal::fake::FaultAction::deliver;
  });
  for (std::uint16_t s = 7; s < 12; ++s) send_meas(s);
  drain();
  // 6 -> 0 is a backward step (dropped, resync), then 0 -> 0 repeats: all 5 dropped.
  EXPECT_EQ(rx.counters().accepted, 3u);
  EXPECT_EQ(rx.counters().dropped_counter, 1u + 5u);
  host.set_fault_hook(nullptr);

  // Hook that drops one id.
  host.set_fault_hook([](CanFrame& f) {
    return f.id == can::id::kTemperature ? hal::fake::FaultAction::drop : hal::fake::FaultAction::deliver;
  });
  CanFrame t{};
  tx.encode(can::Temperature{}, t);
  host.send(t);
  EXPECT_EQ(bms.pending(), 0u);

  host.set_send_status(Status::io_error);
  EXPECT_EQ(send_meas(20), Status::io_error);
  EXPECT_NE(std::string(host.last_error()).find("injected"), std::string::npos);
  EXPECT_EQ(bms.pending(), 0u);
}

TEST(FakeCan, ReceiveQueueOverflowIsCounted) {
  FakeCanBus a, b(3);
  FakeCanBus::connect(a, b);
  for (int k = 0; k < 5; ++k) a.send(frame(0x100));
  EXPECT_EQ(b.pending(), 3u);
  EXPECT_EQ(b.rx_overflows(), 2u);
}

TEST(FakeCan, TimeoutAdvancesALinkedClock) {
  hal::fake::ManualClock clock(1000);
  FakeCanBus a;
  a.set_clock(&clock);
  CanFrame f{};
  EXPECT_EQ(a.receive(f, 50), Status::timeout);
  EXPECT_EQ(clock.now_ns(), 1000u + 50'000'000u);
  EXPECT_EQ(a.receive(f, 0), Status::timeout);
  EXPECT_EQ(clock.now_ns(), 1000u + 50'000'000u);
}

TEST(FakeCan, DisconnectOnDestruction) {
  FakeCanBus a;
  {
    FakeCanBus b;
    FakeCanBus::connect(a, b);
  }
  EXPECT_EQ(a.send(frame(0x100)), Status::ok);  // no peer: lost, no crash
}

// ---------------------------------------------------------------- time

TEST(ManualTime, TicksAndClockMoveOnlyOnRequest) {
  hal::fake::ManualClock clock(5);
  hal::fake::ManualTickSource ticks(&clock);
  std::uint32_t k = 99;
  EXPECT_EQ(ticks.wait_next_tick(k, 1000), Status::timeout);
  EXPECT_EQ(k, 99u);
  ticks.fire(2);
  ASSERT_EQ(ticks.wait_next_tick(k, 0), Status::ok);
  EXPECT_EQ(k, 0u);
  EXPECT_EQ(clock.now_ns(), 5u);
  ASSERT_EQ(ticks.wait_next_tick(k, 0), Status::ok);
  EXPECT_EQ(k, 1u);
  EXPECT_EQ(clock.now_ns(), 5u + hal::kTickPeriodNs);
  ticks.overrun(3);
  ticks.fire();
  ASSERT_EQ(ticks.wait_next_tick(k, 0), Status::ok);
  EXPECT_EQ(k, 5u);
  EXPECT_EQ(ticks.missed_ticks(), 3u);
  EXPECT_EQ(clock.now_ns(), 5u + 5 * hal::kTickPeriodNs);
  clock.set_ns(0);  // monotonic: ignored
  EXPECT_EQ(clock.now_ns(), 5u + 5 * hal::kTickPeriodNs);
  EXPECT_EQ(ticks.period_ns(), 200'000'000u);
}

// ---------------------------------------------------------------- log, watchdog

TEST(RecordingLog, RecordsLevelAndText) {
  hal::fake::RecordingLogSink log;
  hal::LogSink& sink = log;
  sink.write(hal::LogLevel::info, "start");
  sink.write(hal::LogLevel::warning,
             hal::LogLine().add("tick ").add(std::uint32_t{42}).add(" late by ").add(std::int32_t{-7}).add(" ms").c_str());
  ASSERT_EQ(log.entries().size(), 2u);
  EXPECT_EQ(log.entries()[1].message, "tick 42 late by -7 ms");
  EXPECT_EQ(log.count(hal::LogLevel::warning), 1u);
  EXPECT_TRUE(log.contains("late", hal::LogLevel::warning));
  EXPECT_FALSE(log.contains("start", hal::LogLevel::warning));
}

TEST(LogLine, FormatsWithoutPrintfAndCutsSafely) {
  EXPECT_STREQ(hal::LogLine().add(std::int64_t{INT64_MIN}).c_str(), "-9223372036854775808");
  EXPECT_STREQ(hal::LogLine().add(std::uint64_t{0}).c_str(), "0");
  EXPECT_STREQ(hal::LogLine().hex(0x110, 3).c_str(), "0x110");
  EXPECT_STREQ(hal::LogLine().hex(0xABCDEF01u).c_str(), "0xABCDEF01");
  hal::LogLine l;
  for (int i = 0; i < 100; ++i) l.add("0123456789");
  EXPECT_EQ(l.size(), hal::kLogMessageMax - 1);
  EXPECT_EQ(std::strlen(l.c_str()), hal::kLogMessageMax - 1);
}

TEST(CountingWatchdog, CountsKicks) {
  hal::fake::CountingWatchdog wd(500);
  hal::Watchdog& w = wd;
  w.kick();
  w.kick();
  EXPECT_EQ(wd.kicks(), 2u);
  EXPECT_EQ(w.timeout_ms(), 500u);
}

// ---------------------------------------------------------------- lock-step

TEST(LockstepBus, TickFramesDriveTheTickAndReceiveHandsOutExactlyThatTicksFrames) {
  FakeCanBus host, wire;
  FakeCanBus::connect(host, wire);
  can::LockstepTicks decoder;
  hal::LockstepBus<8> bus(
      wire, [](const CanFrame& f, std::uint32_t& t, void* c) { return static_cast<can::LockstepTicks*>(c)->classify(f, t); },
      &decoder);
  hal::CanBus& app_bus = bus;
  hal::TickSource& app_ticks = bus;

  can::Transmitter tx;
  CanFrame f{};
  tx.encode(can::Temperature{}, f);
  host.send(f);
  host.send(measurement_frame(0, 0));
  host.send(measurement_frame(1, 1));  // the next tick's trigger: must not be read ahead

  std::uint32_t tick = 77;
  ASSERT_EQ(app_ticks.wait_next_tick(tick, 10), Status::ok);
  EXPECT_EQ(tick, 0u);
  std::vector<std::uint32_t> ids;
  while (app_bus.receive(f, 1000) == Status::ok) ids.push_back(f.id);
  EXPECT_EQ(ids, (std::vector<std::uint32_t>{can::id::kTemperature, can::id::kMeasurement}));
  EXPECT_EQ(wire.pending(), 1u);

  ASSERT_EQ(app_ticks.wait_next_tick(tick, 10), Status::ok);
  EXPECT_EQ(tick, 1u);
  ASSERT_EQ(app_bus.try_receive(f), Status::ok);
  EXPECT_EQ(app_bus.try_receive(f), Status::timeout);

  // The host goes quiet: the wait times out.
  EXPECT_EQ(app_ticks.wait_next_tick(tick, 10), Status::timeout);
  // Sending goes to the inner bus.
  tx.encode(can::BmsStatus{}, f);
  ASSERT_EQ(app_bus.send(f), Status::ok);
  ASSERT_EQ(host.try_receive(f), Status::ok);
  EXPECT_EQ(f.id, can::id::kStatus);
  EXPECT_EQ(bus.ticks(), 2u);

  // More than the FIFO holds before a trigger: the oldest are dropped and counted.
  for (int k = 0; k < 10; ++k) host.send(frame(0x300));
  host.send(measurement_frame(2, 2));
  ASSERT_EQ(app_ticks.wait_next_tick(tick, 10), Status::ok);
  EXPECT_EQ(tick, 2u);
  EXPECT_EQ(bus.overflowed_frames(), 3u);
  EXPECT_EQ(bus.buffered(), 8u);
}

// A whole firmware-like loop over fakes: lock-step, faults, staleness, status out.
TEST(EndToEnd, LockstepLoopWithFaultsReportsDropsAndStaleness) {
  FakeCanBus host, wire;
  FakeCanBus::connect(host, wire);
  can::LockstepTicks decoder;
  hal::LockstepBus<> bus(
      wire, [](const CanFrame& f, std::uint32_t& t, void* c) { return static_cast<can::LockstepTicks*>(c)->classify(f, t); },
      &decoder);
  can::Transmitter host_tx, bms_tx;
  can::Receiver bms_rx(can::Node::bms), host_rx(can::Node::host);
  can::RxMessage msg;

  auto firmware_step = [&]() {
    std::uint32_t tick = 0;
    if (bus.wait_next_tick(tick, 10) != Status::ok) return false;
    CanFrame f{};
    while (bus.try_receive(f) == Status::ok) bms_rx.accept(f, msg);
    bms_rx.on_tick();
    can::BmsStatus st;
    st.tick_count = tick;
    if (bms_rx.measurement_stale()) st.status_bits |= can::status_bit::kMeasStale;
    bms_tx.encode(st, f);
    bus.send(f);
    bms_tx.encode(bms_rx.rx_stats(), f);
    bus.send(f);
    return true;
  };

  for (std::uint32_t k = 0; k < 12; ++k) {
    CanFrame f{};
    can::Measurement m;
    m.seq = static_cast<std::uint16_t>(k);
    host_tx.encode(m, f);
    if (k >= 4 && k <= 7) host.corrupt_next(6, 0x01);  // 4 ticks of bad CRC
    host.send(f);
    // A corrupted trigger runs one tick (without its sample); the next corrupted ones run
    // none until a good frame comes (LockstepTicks::kMaxUnconfirmedTicks), which then
    // accounts for the ticks in between as missed.
    const bool runs = k < 5 || k > 7;
    ASSERT_EQ(firmware_step(), runs) << k;
    if (!runs) continue;
    // Host reads the status.
    can::BmsStatus last_status;
    can::BmsRxStats last_stats;
    while (host.try_receive(f) == Status::ok) {
      ASSERT_EQ(host_rx.accept(f, msg), can::RxResult::accepted);
      if (msg.msg == can::Msg::status) last_status = msg.status;
      if (msg.msg == can::Msg::rx_stats) last_stats = msg.rx_stats;
    }
    EXPECT_EQ(last_status.tick_count, k);
    const bool stale = (last_status.status_bits & can::status_bit::kMeasStale) != 0;
    EXPECT_FALSE(stale) << "tick " << k << ": at most one tick in a row ran without a sample";
    if (k == 11) {
      EXPECT_EQ(last_stats.drop_crc, 4);
      EXPECT_EQ(last_stats.ticks_without_meas, 0);
    }
  }
  EXPECT_EQ(bms_rx.counters().stale_events, 0u);
  EXPECT_EQ(decoder.unconfirmed_refused(), 3u);
  EXPECT_EQ(bms_rx.counters().accepted, 8u);
  EXPECT_EQ(bms_rx.counters().lost_frames, 4u);
}
