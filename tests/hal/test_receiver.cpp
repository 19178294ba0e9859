// The validating receiver: drops and counts wrong length, bad CRC, repeated/frozen or
// out-of-sequence counters; ignores unknown ids; staleness after > 2 missing ticks.
// Also the lock-step tick classifier.
#include <gtest/gtest.h>

#include "bms/fw/can/can_protocol.hpp"
#include "bms/hal/can_bus.hpp"

namespace can = bms::fw::can;
using bms::hal::CanFrame;

namespace {

CanFrame measurement(std::uint8_t counter, std::uint16_t seq = 0, double v = 3.3, double i = -2.5) {
  can::Measurement m;
  m.seq = seq;
  m.voltage_v = v;
  m.current_a = i;
  CanFrame f{};
  can::encode(m, counter, f);
  return f;
}

}  // namespace

TEST(Receiver, AcceptsAValidSequenceAndDecodes) {
  can::Receiver rx;
  can::RxMessage msg;
  for (std::uint8_t k = 0; k < 40; ++k) {
    ASSERT_EQ(rx.accept(measurement(k & 0xF, k, 3.0 + k * 1e-5, -1.0), msg), can::RxResult::accepted) << int(k);
    EXPECT_EQ(msg.msg, can::Msg::measurement);
    EXPECT_EQ(msg.measurement.seq, k);
    EXPECT_NEAR(msg.measurement.voltage_v, 3.0 + k * 1e-5, 5e-6);
    EXPECT_NEAR(msg.measurement.current_a, -1.0, 5e-5);
  }
  EXPECT_EQ(rx.counters().accepted, 40u);
  EXPECT_EQ(rx.counters().dropped_total(), 0u);
  EXPECT_EQ(rx.counters().lost_frames, 0u);
}

TEST(Receiver, DropsAndCountsWrongLength) {
  can::Receiver rx;
  can::RxMessage msg;
  CanFrame f = measurement(0);
  f.len = 7;
  EXPECT_EQ(rx.accept(f, msg), can::RxResult::dropped_length);
  f.len = 0;
  EXPECT_EQ(rx.accept(f, msg), can::RxResult::dropped_length);
  can::Temperature t;
  CanFrame g{};
  can::encode(t, 0, g);
  g.len = 8;  // Temperature is 4 bytes
  EXPECT_EQ(rx.accept(g, msg), can::RxResult::dropped_length);
  EXPECT_EQ(rx.counters().dropped_length, 3u);
  EXPECT_EQ(rx.counters().accepted, 0u);
  // A correct frame after them is fine.
  EXPECT_EQ(rx.accept(measurement(1), msg), can::RxResult::accepted);
}

TEST(Receiver, DropsAndCountsBadCrc) {
  can::Receiver rx;
  can::RxMessage msg;
  for (int byte = 0; byte < 8; ++byte) {
    for (int bit = 0; bit < 8; ++bit) {
      CanFrame f = measurement(static_cast<std::uint8_t>(byte));
      f.data[byte] = static_cast<std::uint8_t>(f.data[byte] ^ (1u << bit));  // any single-bit error
      EXPECT_EQ(rx.accept(f, msg), can::RxResult::dropped_crc) << byte << ":" << bit;
    }
  }
  EXPECT_EQ(rx.counters().dropped_crc, 64u);
  // A frame whose id was corrupted into another valid id with the same length.
  can::Control c;
  CanFrame f{};
  can::encode(c, 0, f);
  f.id = can::id::kMeasurement;
  EXPECT_EQ(rx.accept(f, msg), can::RxResult::dropped_crc);
  EXPECT_EQ(rx.counters().dropped_crc, 65u);
  EXPECT_EQ(rx.counters().accepted, 0u);
}

TEST(Receiver, DropsRepeatedAndFrozenCounters) {
  can::Receiver rx;
  can::RxMessage msg;
  EXPECT_EQ(rx.accept(measurement(4), msg), can::RxResult::accepted);
  EXPECT_EQ(rx.accept(measurement(4), msg), can::RxResult::dropped_counter);  // repeated
  for (int k = 0; k < 10; ++k)                                                  // frozen
    EXPECT_EQ(rx.accept(measurement(4, static_cast<std::uint16_t>(k + 1)), msg), can::RxResult::dropped_counter);
  EXPECT_EQ(rx.counters().dropped_counter, 11u);
  EXPECT_EQ(rx.accept(measurement(5), msg), can::RxResult::accepted);
  // Counters are per message: a Control with counter 5 is not a repeat.
  can::Control c;
  CanFrame f{};
  can::encode(c, 5, f);
  EXPECT_EQ(rx.accept(f, msg), can::RxResult::accepted);
  EXPECT_EQ(msg.msg, can::Msg::control);
}

TEST(Receiver, CountsGapsAndDropsBackwardSteps) {
  can::Receiver rx;
  can::RxMessage msg;
  EXPECT_EQ(rx.accept(measurement(14), msg), can::RxResult::accepted);
  EXPECT_EQ(rx.accept(measurement(1), msg), can::RxResult::accepted);  // 15, 0 lost (wraps)
  EXPECT_EQ(rx.counters().lost_frames, 2u);
  EXPECT_EQ(rx.accept(measurement(8), msg), can::RxResult::accepted);  // step 7: 6 lost
  EXPECT_EQ(rx.counters().lost_frames, 8u);
  EXPECT_EQ(rx.accept(measurement(7), msg), can::RxResult::dropped_counter);  // old frame (step 15)
  EXPECT_EQ(rx.accept(measurement(8), msg), can::RxResult::accepted);  // resynced on 7
  EXPECT_EQ(rx.accept(measurement(0), msg), can::RxResult::dropped_counter);  // step 8: too far
  EXPECT_EQ(rx.counters().dropped_counter, 2u);
  EXPECT_EQ(rx.accept(measurement(1), msg), can::RxResult::accepted);  // restarted sender: one frame lost
}

TEST(Receiver, IgnoresUnknownIdsWithoutCountingAnError) {
  can::Receiver rx;
  can::RxMessage msg;
  CanFrame f = measurement(0);
  for (std::uint32_t id : {0x000u, 0x7FFu, 0x10Fu, 0x112u, 0x123u}) {
    f.id = id;
    EXPECT_EQ(rx.accept(f, msg), can::RxResult::ignored_id) << id;
  }
  // Messages the BMS itself sends are not for the BMS receiver.
  can::BmsStatus s;
  CanFrame g{};
  can::encode(s, 0, g);
  EXPECT_EQ(rx.accept(g, msg), can::RxResult::ignored_id);
  EXPECT_EQ(rx.counters().ignored_id, 6u);
  EXPECT_EQ(rx.counters().dropped_total(), 0u);
  // Unknown ids with a garbage length are still only ignored.
  f.id = 0x555;
  f.len = 3;
  EXPECT_EQ(rx.accept(f, msg), can::RxResult::ignored_id);
  EXPECT_EQ(rx.counters().dropped_length, 0u);
}

TEST(Receiver, HostSideAcceptsBmsMessages) {
  can::Receiver rx(can::Node::host);
  can::RxMessage msg;
  can::Estimate1 e;
  e.r_film_ohm_m2 = 3.4e-3;
  CanFrame f{};
  can::encode(e, 9, f);
  EXPECT_EQ(rx.accept(f, msg), can::RxResult::accepted);
  EXPECT_EQ(msg.msg, can::Msg::estimate1);
  EXPECT_NEAR(msg.estimate1.r_film_ohm_m2, 3.4e-3, 1e-10);
  EXPECT_EQ(rx.accept(measurement(0), msg), can::RxResult::ignored_id);
}

TEST(Receiver, FlagsStalenessAfterMoreThanTwoMissingTicksAndClearsIt) {
  can::Receiver rx;
  can::RxMessage msg;
  std::uint8_t c = 0;
  for (int k = 0; k < 5; ++k) {
    ASSERT_EQ(rx.accept(measurement(c++ & 0xF), msg), can::RxResult::accepted);
    rx.on_tick();
    EXPECT_FALSE(rx.measurement_stale());
    EXPECT_EQ(rx.ticks_without_measurement(), 0u);
  }
  rx.on_tick();
  rx.on_tick();
  EXPECT_EQ(rx.ticks_without_measurement(), 2u);
  EXPECT_FALSE(rx.measurement_stale()) << "2 missing ticks are tolerated";
  // Dropped frames do not count as measurements.
  CanFrame bad = measurement(c & 0xF);
  bad.data[3] ^= 0x01;
  EXPECT_EQ(rx.accept(bad, msg), can::RxResult::dropped_crc);
  rx.on_tick();
  EXPECT_EQ(rx.ticks_without_measurement(), 3u);
  EXPECT_TRUE(rx.measurement_stale());
  EXPECT_EQ(rx.counters().stale_events, 1u);
  for (int k = 0; k < 10; ++k) rx.on_tick();
  EXPECT_TRUE(rx.measurement_stale());
  EXPECT_EQ(rx.counters().stale_events, 1u);
  EXPECT_EQ(rx.rx_stats().ticks_without_meas, 13);
  // A valid frame clears it at once.
  EXPECT_EQ(rx.accept(measurement(c++ & 0xF), msg), can::RxResult::accepted);
  EXPECT_FALSE(rx.measurement_stale());
  EXPECT_EQ(rx.ticks_without_measurement(), 0u);
  rx.on_tick();
  EXPECT_FALSE(rx.measurement_stale());
  // Other messages do not keep the measurement fresh.
  for (int k = 0; k < 3; ++k) {
    can::Temperature t;
    CanFrame f{};
    can::encode(t, static_cast<std::uint8_t>(k), f);
    EXPECT_EQ(rx.accept(f, msg), can::RxResult::accepted);
    rx.on_tick();
  }
  EXPECT_TRUE(rx.measurement_stale());
  EXPECT_EQ(rx.counters().stale_events, 2u);
}

TEST(Receiver, RxStatsReportsCountersModulo256) {
  can::Receiver rx;
  can::RxMessage msg;
  CanFrame f = measurement(0);
  f.len = 2;
  for (int k = 0; k < 300; ++k) rx.accept(f, msg);
  EXPECT_EQ(rx.counters().dropped_length, 300u);
  EXPECT_EQ(rx.rx_stats().drop_length, 300 % 256);
  for (int k = 0; k < 300; ++k) rx.on_tick();
  EXPECT_EQ(rx.rx_stats().ticks_without_meas, 255);
  rx.reset();
  EXPECT_EQ(rx.counters().dropped_length, 0u);
  EXPECT_EQ(rx.ticks_without_measurement(), 0u);
}

TEST(LockstepTicks, MeasurementSeqUnwrapsTo32Bits) {
  can::LockstepTicks lt;
  std::uint32_t tick = 0;
  EXPECT_TRUE(lt.classify(measurement(0, 4094), tick));
  EXPECT_EQ(tick, 4094u);
  EXPECT_TRUE(lt.classify(measurement(1, 4095), tick));
  EXPECT_EQ(tick, 4095u);
  EXPECT_TRUE(lt.classify(measurement(2, 0), tick));
  EXPECT_EQ(tick, 4096u);
  EXPECT_TRUE(lt.classify(measurement(3, 5), tick));
  EXPECT_EQ(tick, 4101u);
  // A duplicated or late (reordered) frame is not a new tick.
  EXPECT_FALSE(lt.classify(measurement(9, 5), tick));
  EXPECT_FALSE(lt.classify(measurement(9, 3), tick));
  EXPECT_EQ(lt.last_tick(), 4101u);
  // A corrupted measurement still triggers the next tick (the receiver then drops it).
  CanFrame bad = measurement(4, 6);
  bad.data[2] ^= 0xFF;
  EXPECT_TRUE(lt.classify(bad, tick));
  EXPECT_EQ(tick, 4102u);
  // Wrong length does not trigger; other ids do not.
  bad = measurement(5, 7);
  bad.len = 6;
  EXPECT_FALSE(lt.classify(bad, tick));
  can::Temperature t;
  CanFrame tf{};
  can::encode(t, 0, tf);
  EXPECT_FALSE(lt.classify(tf, tick));
}

TEST(LockstepTicks, ControlTickTriggerSetsTheFullNumber) {
  can::LockstepTicks lt;
  std::uint32_t tick = 0;
  can::Control c;
  c.lockstep = true;
  c.tick = 100000;
  CanFrame f{};
  can::encode(c, 0, f);
  EXPECT_FALSE(lt.classify(f, tick)) << "TickTrigger = 0";
  c.tick_trigger = true;
  can::encode(c, 1, f);
  EXPECT_TRUE(lt.classify(f, tick));
  EXPECT_EQ(tick, 100000u);
  EXPECT_TRUE(lt.classify(measurement(0, static_cast<std::uint16_t>(100001 & 0xFFF)), tick));
  EXPECT_EQ(tick, 100001u);
  f.data[0] ^= 1;  // bad CRC: a control frame cannot be trusted to trigger
  EXPECT_FALSE(lt.classify(f, tick));
}

// ---------------------------------------------------------------- sequence window

TEST(Receiver, SeqWindowDropsAStaleFrameBeforeItsCounterCanPushTheGenuineOneOut) {
  // Tick 11's genuine frame has counter 2 (tick 10's had 1). An old CRC-valid frame (Seq 5)
  // whose counter is 3 ahead arrives first: without the window it was accepted and the
  // genuine one then dropped as a backward counter step.
  for (bool window : {false, true}) {
    can::Receiver rx;
    can::RxMessage msg;
    ASSERT_EQ(rx.accept(measurement(1, 10, 3.30), msg), can::RxResult::accepted);
    if (window) rx.set_seq_window(11, 1);
    const can::RxResult old = rx.accept(measurement(4, 5, 3.10), msg);
    const can::RxResult genuine = rx.accept(measurement(2, 11, 3.31), msg);
    if (!window) {
      EXPECT_EQ(old, can::RxResult::accepted) << "the attack the window closes";
      EXPECT_EQ(genuine, can::RxResult::dropped_counter);
      continue;
    }
    EXPECT_EQ(old, can::RxResult::dropped_seq);
    EXPECT_EQ(rx.last_rejected_seq(), 5u);
    ASSERT_EQ(genuine, can::RxResult::accepted);
    EXPECT_EQ(msg.measurement.seq, 11u);
    EXPECT_NEAR(msg.measurement.voltage_v, 3.31, 1e-5);
    EXPECT_EQ(rx.counters().dropped_seq, 1u);
    EXPECT_EQ(rx.counters().dropped_counter, 0u);
    EXPECT_EQ(rx.rx_stats().drop_counter, 1) << "DropCounter carries sequence drops too";
  }
}

TEST(Receiver, SeqWindowWrapsAndAnEmptyWindowLetsNoMeasurementPass) {
  can::Receiver rx;
  can::RxMessage msg;
  rx.set_seq_window(4094, 4);  // 4094, 4095, 0, 1
  EXPECT_EQ(rx.accept(measurement(0, 4095), msg), can::RxResult::accepted);
  EXPECT_EQ(rx.accept(measurement(1, 1), msg), can::RxResult::accepted);
  EXPECT_EQ(rx.accept(measurement(2, 2), msg), can::RxResult::dropped_seq);
  rx.set_seq_window(0, 0);
  EXPECT_EQ(rx.accept(measurement(2, 0), msg), can::RxResult::dropped_seq);
  // Other messages are not subject to it.
  can::Temperature t;
  CanFrame f{};
  can::encode(t, 0, f);
  EXPECT_EQ(rx.accept(f, msg), can::RxResult::accepted);
  rx.clear_seq_window();
  EXPECT_EQ(rx.accept(measurement(2, 3000), msg), can::RxResult::accepted);
}

TEST(SeqTracker, AdoptsWithinTheWindowAndResyncsOnThreeConsecutiveFrames) {
  using V = can::SeqTracker::Verdict;
  can::SeqTracker t;
  EXPECT_EQ(t.observe(1000, 50), V::first);
  EXPECT_EQ(t.observe(1001, 50), V::in_window);
  EXPECT_EQ(t.observe(1051, 50), V::in_window);
  EXPECT_EQ(t.step(), 50u);
  EXPECT_EQ(t.observe(1102, 50), V::rejected) << "51 ahead: one frame may not claim it";
  EXPECT_EQ(t.observe(1051, 50), V::rejected) << "a repeat";
  // A host restarting at 0: frames 0, 1, 2 -> adopted at the third, as one step.
  EXPECT_EQ(t.observe(0, 50), V::rejected);
  EXPECT_EQ(t.observe(1, 50), V::rejected);
  EXPECT_EQ(t.observe(2, 50), V::restart);
  EXPECT_EQ(t.step(), 1u);
  EXPECT_EQ(t.last(), 2u);
  EXPECT_EQ(t.observe(3, 50), V::in_window);
  // A long gap (300 ticks): confirmed by three consecutive frames, then a known jump.
  EXPECT_EQ(t.observe(303, 50), V::rejected);
  EXPECT_EQ(t.observe(304, 50), V::rejected);
  EXPECT_EQ(t.observe(305, 50), V::jump);
  EXPECT_EQ(t.step(), 302u);
  // Non-consecutive rejected frames never resync.
  for (int s : {100, 200, 101, 300, 102, 103})
    EXPECT_EQ(t.observe(static_cast<std::uint16_t>(s), 50), V::rejected) << s;
  EXPECT_EQ(t.last(), 305u);
  EXPECT_EQ(t.resyncs(), 2u);
}

TEST(LockstepTicks, OneFrameCannotClaimMoreThanTheStepLimit) {
  // The issue: one HOST_Control frame with Tick = last + 266 faked 265 missed ticks.
  can::LockstepTicks lt;
  std::uint32_t tick = 0;
  can::Transmitter tx;
  auto control = [&](std::uint32_t t) {
    can::Control c;
    c.tick_trigger = true;
    c.tick = t;
    CanFrame f{};
    tx.encode(c, f);
    return f;
  };
  ASSERT_TRUE(lt.classify(measurement(0, 100), tick));
  EXPECT_FALSE(lt.classify(control(100 + 266), tick));
  EXPECT_EQ(lt.last_tick(), 100u);
  EXPECT_TRUE(lt.classify(control(100 + can::LockstepTicks::kMaxTickStep), tick));
  EXPECT_EQ(tick, 150u);
  EXPECT_FALSE(lt.classify(measurement(1, static_cast<std::uint16_t>(150 + 51)), tick));
  EXPECT_TRUE(lt.classify(measurement(1, 151), tick));
  EXPECT_EQ(tick, 151u);
}

TEST(LockstepTicks, CorruptedCopiesRunAtMostOneTickAndDoNotStallTheGoodFrames) {
  // The issue: 40 corrupted copies of one frame ran 40 extra ticks, then the next 39 good
  // frames (Seq behind the run-away tick) triggered nothing.
  can::LockstepTicks lt;
  std::uint32_t tick = 0;
  ASSERT_TRUE(lt.classify(measurement(0, 10), tick));
  CanFrame bad = measurement(1, 11);
  bad.data[5] ^= 0x40;
  int extra = 0;
  for (int k = 0; k < 40; ++k) extra += lt.classify(bad, tick) ? 1 : 0;
  EXPECT_EQ(extra, 1);
  EXPECT_EQ(tick, 11u);
  std::uint16_t seq = 0;
  EXPECT_FALSE(lt.tick_seq(seq)) << "no measurement belongs to a tick run on a corrupted frame";
  // The genuine frame of tick 11 already ran (without its sample); 12.. trigger at once.
  EXPECT_FALSE(lt.classify(measurement(1, 11), tick));
  for (std::uint16_t s = 12; s < 52; ++s) {
    ASSERT_TRUE(lt.classify(measurement(static_cast<std::uint8_t>(s & 0xF), s), tick)) << s;
    EXPECT_EQ(tick, s);
    ASSERT_TRUE(lt.tick_seq(seq));
    EXPECT_EQ(seq, s);
  }
  EXPECT_EQ(lt.unconfirmed_refused(), 39u);
}

TEST(LockstepTicks, ARestartedHostIsFollowedAfterThreeFrames) {
  // The issue: a host restarting Seq at 0 got no tick for up to 2047 ticks.
  can::LockstepTicks lt;
  std::uint32_t tick = 0;
  for (std::uint16_t s = 1000; s < 1010; ++s) ASSERT_TRUE(lt.classify(measurement(0, s), tick));
  EXPECT_EQ(tick, 1009u);
  EXPECT_FALSE(lt.classify(measurement(0, 0), tick));
  EXPECT_FALSE(lt.classify(measurement(1, 1), tick));
  ASSERT_TRUE(lt.classify(measurement(2, 2), tick));
  EXPECT_EQ(tick, 1010u) << "the restart is one step: the gap is unknown";
  std::uint16_t seq = 0;
  ASSERT_TRUE(lt.tick_seq(seq));
  EXPECT_EQ(seq, 2u);
  ASSERT_TRUE(lt.classify(measurement(3, 3), tick));
  EXPECT_EQ(tick, 1011u);
  EXPECT_EQ(lt.resyncs(), 1u);
}
