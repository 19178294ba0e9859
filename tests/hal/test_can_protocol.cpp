// The frame codec: CRC, bit layout, and round trips of every message at the extremes of
// its ranges and at single resolution steps.
#include <gtest/gtest.h>

#include <cfloat>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>

#include "bms/fw/can/can_protocol.hpp"
#include "bms/fw/model/paper_cell.hpp"
#include "bms/hal/can_bus.hpp"

namespace can = bms::fw::can;
using bms::hal::CanFrame;

namespace {

// Independent bit-by-bit CRC-8/SAE-J1850, to check the table-driven one.
std::uint8_t crc8_reference(const std::uint8_t* d, std::size_t n) {
  unsigned crc = 0xFF;
  for (std::size_t i = 0; i < n; ++i) {
    crc ^= d[i];
    for (int b = 0; b < 8; ++b) crc = (crc & 0x80u) ? ((crc << 1u) ^ 0x1Du) & 0xFFu : (crc << 1u) & 0xFFu;
  }
  return static_cast<std::uint8_t>(crc ^ 0xFFu);
}

template <class M>
M round_trip(const M& in, std::uint8_t counter = 3) {
  CanFrame f{};
  can::encode(in, counter, f);
  EXPECT_EQ(f.len, can::layout(can::MessageTraits<M>::kMsg).dlc);
  EXPECT_EQ(f.id, can::layout(can::MessageTraits<M>::kMsg).id);
  EXPECT_TRUE(can::frame_crc_ok(f));
  EXPECT_EQ(can::frame_counter(f.data), counter & 0xF);
  M out{};
  EXPECT_TRUE(can::decode(f, out));
  return out;
}

template <class M>
std::int64_t raw_of(const M& m, const can::SignalLayout& s) {
  CanFrame f{};
  can::encode(m, 0, f);
  const std::uint64_t raw = can::get_bits(f.data, s.start_bit, s.length);
  return s.type == can::ValueType::signed_int ? can::sign_extend(raw, s.length) : static_cast<std::int64_t>(raw);
}

}  // namespace

TEST(Crc8, CatalogueCheckValue) {
  const char* s = "123456789";
  const auto* d = reinterpret_cast<const std::uint8_t*>(s);
  EXPECT_EQ(can::crc8_sae_j1850(d, 9), 0x4B);
  EXPECT_EQ(crc8_reference(d, 9), 0x4B);
  std::uint8_t all[256];
  for (int i = 0; i < 256; ++i) all[i] = static_cast<std::uint8_t>(i * 7 + 1);
  for (std::size_t n = 0; n <= 256; n += 17) EXPECT_EQ(can::crc8_sae_j1850(all, n), crc8_reference(all, n)) << n;
}

TEST(Crc8, FrameCrcCoversIdAndPayloadButNotByteZero) {
  std::uint8_t d[8] = {0, 1, 2, 3, 4, 5, 6, 7};
  const std::uint8_t ref_in[9] = {0x10, 0x01, 1, 2, 3, 4, 5, 6, 7};
  EXPECT_EQ(can::frame_crc(0x110, d, 8), crc8_reference(ref_in, 9));
  d[0] = 0xAA;  // byte 0 is the CRC's place: not covered
  EXPECT_EQ(can::frame_crc(0x110, d, 8), crc8_reference(ref_in, 9));
  EXPECT_NE(can::frame_crc(0x111, d, 8), can::frame_crc(0x110, d, 8));
  EXPECT_NE(can::frame_crc(0x110, d, 7), can::frame_crc(0x110, d, 8));
}

TEST(Layout, SignalsFitTheirFrameAndDoNotOverlap) {
  for (const auto& m : can::kMessages) {
    SCOPED_TRACE(m.name);
    std::uint64_t used = 0;
    ASSERT_GE(m.signal_count, 2u);
    EXPECT_STREQ(m.signals[0].name, "Crc");
    EXPECT_EQ(m.signals[0].start_bit, 0);
    EXPECT_EQ(m.signals[0].length, 8);
    EXPECT_STREQ(m.signals[1].name, "Counter");
    EXPECT_EQ(m.signals[1].start_bit, 8);
    EXPECT_EQ(m.signals[1].length, 4);
    EXPECT_NE(m.sender, m.receiver);
    EXPECT_EQ(can::message_index(m.id), static_cast<int>(&m - can::kMessages));
    for (std::size_t i = 0; i < m.signal_count; ++i) {
      const auto& s = m.signals[i];
      EXPECT_GE(s.length, 1);
      EXPECT_LE(s.start_bit + s.length, m.dlc * 8) << s.name;
      if (s.type == can::ValueType::float32) {
        EXPECT_EQ(s.length, 32) << s.name;
        continue;
      }
      const std::uint64_t mask = (s.length == 64 ? ~0ull : ((1ull << s.length) - 1u)) << s.start_bit;
      EXPECT_EQ(used & mask, 0u) << s.name << " overlaps";
      used |= mask;
      // The DBC range is exactly the raw range.
      EXPECT_NEAR(s.min, can::from_raw(s, can::raw_min(s)), 1e-9 * std::fabs(s.factor)) << s.name;
      EXPECT_NEAR(s.max, can::from_raw(s, can::raw_max(s)), 1e-9 * std::max(1.0, std::fabs(s.max))) << s.name;
    }
  }
  EXPECT_EQ(can::message_index(0x7FF), -1);
}

TEST(Layout, ResolutionAndRangeMeetTheRequirements) {
  EXPECT_LE(can::sig::kMeasVoltage.factor, 10e-6);  // at most 10 uV
  EXPECT_LE(can::sig::kMeasCurrent.factor, 0.1e-3);  // at most 0.1 mA
  EXPECT_GE(can::sig::kMeasVoltage.max, 5.5);
  EXPECT_LE(can::sig::kMeasVoltage.min, 0.0);
  EXPECT_GE(can::sig::kMeasCurrent.max, 50.0);
  EXPECT_LE(can::sig::kMeasCurrent.min, -50.0);
  EXPECT_LE(can::sig::kRFilm.factor, 1e-9);
  EXPECT_GE(can::sig::kRFilm.max, 0.1);
}

// Hand-assembled frame: pins the bit layout independently of put_bits/get_bits.
TEST(Layout, GoldenMeasurementFrame) {
  can::Measurement m;
  m.seq = 0x123;
  m.voltage_v = 3.3;    // raw 330000 = 0x50910
  m.current_a = -2.5;   // raw -25000 -> 20-bit 0xF9E58
  CanFrame f{};
  can::encode(m, 5, f);
  const std::uint8_t payload[8] = {0, 0x35, 0x12, 0x10, 0x09, 0x85, 0xE5, 0xF9};
  for (int i = 1; i < 8; ++i) EXPECT_EQ(f.data[i], payload[i]) << "byte " << i;
  const std::uint8_t crc_in[9] = {0x10, 0x01, 0x35, 0x12, 0x10, 0x09, 0x85, 0xE5, 0xF9};
  EXPECT_EQ(f.data[0], crc8_reference(crc_in, 9));
  EXPECT_EQ(f.id, 0x110u);
  EXPECT_EQ(f.len, 8);
}

TEST(RoundTrip, MeasurementExtremesAndSteps) {
  const double dv = can::sig::kMeasVoltage.factor;
  const double di = can::sig::kMeasCurrent.factor;
  for (double v : {0.0, dv, 2.0, 3.6, 5.5, 5.5 + dv, can::sig::kMeasVoltage.max - dv, can::sig::kMeasVoltage.max}) {
    for (double i : {-50.0, -2.5, -di, 0.0, di, 2.5, 50.0, can::sig::kMeasCurrent.min, can::sig::kMeasCurrent.max}) {
      can::Measurement m;
      m.seq = 4095;
      m.voltage_v = v;
      m.current_a = i;
      const can::Measurement r = round_trip(m);
      EXPECT_EQ(r.seq, 4095);
      EXPECT_NEAR(r.voltage_v, v, dv / 2 + 1e-12);
      EXPECT_NEAR(r.current_a, i, di / 2 + 1e-12);
    }
  }
  // One step apart encodes one raw count apart; the paper's noise levels are resolved.
  can::Measurement a, b;
  a.voltage_v = 3.30000;
  b.voltage_v = 3.30001;
  a.current_a = -2.5;
  b.current_a = -2.4999;
  EXPECT_EQ(raw_of(b, can::sig::kMeasVoltage) - raw_of(a, can::sig::kMeasVoltage), 1);
  EXPECT_EQ(raw_of(b, can::sig::kMeasCurrent) - raw_of(a, can::sig::kMeasCurrent), 1);
  b.voltage_v = a.voltage_v + 0.02e-3;
  EXPECT_EQ(raw_of(b, can::sig::kMeasVoltage) - raw_of(a, can::sig::kMeasVoltage), 2);
  b.current_a = a.current_a + 0.5e-3;
  EXPECT_EQ(raw_of(b, can::sig::kMeasCurrent) - raw_of(a, can::sig::kMeasCurrent), 5);
}

TEST(RoundTrip, MeasurementSaturatesAndWrapsSeq) {
  can::Measurement m;
  m.seq = 4096 + 7;
  m.voltage_v = 99.0;
  m.current_a = -1e6;
  can::Measurement r = round_trip(m);
  EXPECT_EQ(r.seq, 7);
  EXPECT_DOUBLE_EQ(r.voltage_v, can::sig::kMeasVoltage.max);
  EXPECT_DOUBLE_EQ(r.current_a, can::sig::kMeasCurrent.min);
  m.voltage_v = -1.0;
  m.current_a = std::numeric_limits<double>::infinity();
  r = round_trip(m);
  EXPECT_DOUBLE_EQ(r.voltage_v, 0.0);
  EXPECT_DOUBLE_EQ(r.current_a, can::sig::kMeasCurrent.max);
  // NaN (a failed ADC read) goes to the end of the raw range a plausibility check rejects,
  // never to 0, which would read as a plausible 0 A.
  m.voltage_v = std::numeric_limits<double>::quiet_NaN();
  m.current_a = std::numeric_limits<double>::quiet_NaN();
  r = round_trip(m);
  EXPECT_DOUBLE_EQ(r.voltage_v, can::sig::kMeasVoltage.max);
  EXPECT_DOUBLE_EQ(r.current_a, can::sig::kMeasCurrent.min);
}

TEST(RoundTrip, Control) {
  for (int bits = 0; bits < 8; ++bits) {
    for (std::uint32_t tick : {0u, 1u, 4096u, 0xFFFFFFFFu}) {
      can::Control c;
      c.reset_estimator = (bits & 1) != 0;
      c.lockstep = (bits & 2) != 0;
      c.tick_trigger = (bits & 4) != 0;
      c.tick = tick;
      const can::Control r = round_trip(c, static_cast<std::uint8_t>(bits * 2));
      EXPECT_EQ(r.reset_estimator, c.reset_estimator);
      EXPECT_EQ(r.lockstep, c.lockstep);
      EXPECT_EQ(r.tick_trigger, c.tick_trigger);
      EXPECT_EQ(r.tick, tick);
    }
  }
}

TEST(RoundTrip, Temperature) {
  for (double t : {0.0, 0.01, 233.15, 298.15, 655.34, 655.35}) {
    can::Temperature m;
    m.temperature_k = t;
    EXPECT_NEAR(round_trip(m).temperature_k, t, 0.005 + 1e-9);
  }
  can::Temperature a, b;
  a.temperature_k = 298.15;
  b.temperature_k = 298.16;
  EXPECT_EQ(raw_of(b, can::sig::kTemperature) - raw_of(a, can::sig::kTemperature), 1);
}

TEST(RoundTrip, Estimate1) {
  const double step = can::sig::kRFilm.factor;
  for (double r : {0.0, step, 1e-9, bms::fw::paper::kInitialFilm_ohm_m2, bms::fw::paper::kInitialFilm_ohm_m2 + 1e-9, 0.1, can::sig::kRFilm.max}) {
    for (int mode : {0, 1, 2, 3, 4, 15}) {
      can::Estimate1 e;
      e.seq = 2048;
      e.r_film_ohm_m2 = r;
      e.mode = static_cast<can::Mode>(mode);
      e.rcsi_active = mode == 3;
      e.valid = mode != 15;
      const can::Estimate1 o = round_trip(e);
      EXPECT_EQ(o.seq, 2048);
      EXPECT_NEAR(o.r_film_ohm_m2, r, step / 2 + 1e-18);
      EXPECT_EQ(o.mode, e.mode);
      EXPECT_EQ(o.rcsi_active, e.rcsi_active);
      EXPECT_EQ(o.valid, e.valid);
    }
  }
  can::Estimate1 a, b;
  a.r_film_ohm_m2 = bms::fw::paper::kInitialFilm_ohm_m2;
  b.r_film_ohm_m2 = bms::fw::paper::kInitialFilm_ohm_m2 + 1e-9;  // 1e-9 ohm.m2 is resolved (10 steps)
  EXPECT_EQ(raw_of(b, can::sig::kRFilm) - raw_of(a, can::sig::kRFilm), 10);
  a.r_film_ohm_m2 = 1.0;  // saturates
  EXPECT_DOUBLE_EQ(round_trip(a).r_film_ohm_m2, can::sig::kRFilm.max);
  a.r_film_ohm_m2 = -1e-3;
  EXPECT_DOUBLE_EQ(round_trip(a).r_film_ohm_m2, 0.0);
}

TEST(RoundTrip, ThetaFloatsAreBitExact) {
  const float values[] = {0.0f, -0.0f, 1.0f, -2.3712e-10f, 1e-10f, 1e-7f, 1e-4f, FLT_MAX, -FLT_MAX,
                          FLT_MIN, FLT_TRUE_MIN, std::numeric_limits<float>::infinity(),
                          std::numeric_limits<float>::quiet_NaN()};
  for (float v : values) {
    can::Estimate2 e2;
    e2.seq = 1;
    e2.theta0 = v;
    can::Estimate3 e3;
    e3.seq = 4095;
    e3.theta1 = v;
    const can::Estimate2 r2 = round_trip(e2);
    const can::Estimate3 r3 = round_trip(e3);
    EXPECT_EQ(std::memcmp(&r2.theta0, &v, sizeof v), 0) << v;
    EXPECT_EQ(std::memcmp(&r3.theta1, &v, sizeof v), 0) << v;
    EXPECT_EQ(r2.seq, 1);
    EXPECT_EQ(r3.seq, 4095);
  }
  // IEEE-754 little-endian in bytes 4..7: 1.0f = 0x3F800000.
  can::Estimate2 e;
  e.theta0 = 1.0f;
  CanFrame f{};
  can::encode(e, 0, f);
  EXPECT_EQ(f.data[4], 0x00);
  EXPECT_EQ(f.data[5], 0x00);
  EXPECT_EQ(f.data[6], 0x80);
  EXPECT_EQ(f.data[7], 0x3F);
}

TEST(RoundTrip, Health) {
  const double step_ah = can::sig::kLiLoss.factor / can::kMahPerAh;  // 1e-7 Ah
  const double step_v = can::sig::kZResidual.factor / can::kUvPerV;   // 1e-6 V
  for (double li : {0.0, step_ah, 1e-3, 0.05, can::sig::kLiLoss.max / can::kMahPerAh}) {
    for (double z : {-32768e-6, -step_v, 0.0, step_v, 20e-6, 32767e-6}) {
      can::Health h;
      h.seq = 77;
      h.li_loss_ah = li;
      h.z_v = z;
      const can::Health r = round_trip(h);
      EXPECT_EQ(r.seq, 77);
      EXPECT_NEAR(r.li_loss_ah, li, step_ah / 2 + 1e-15);
      EXPECT_NEAR(r.z_v, z, step_v / 2 + 1e-15);
    }
  }
  can::Health a, b;
  a.li_loss_ah = 0.001;
  b.li_loss_ah = 0.001 + 1e-7;
  EXPECT_EQ(raw_of(a, can::sig::kLiLoss), 10000);  // 1 mAh on the bus
  EXPECT_EQ(raw_of(b, can::sig::kLiLoss) - raw_of(a, can::sig::kLiLoss), 1);
  a.z_v = -1.0;  // saturates
  EXPECT_DOUBLE_EQ(round_trip(a).z_v, -32768e-6);
}

TEST(RoundTrip, Uncertainty) {
  const double step_sd = can::sig::kRFilmSd.factor;                          // 1e-8 ohm m2
  const double step_cap = can::sig::kCapacity.factor / can::kMahPerAh;      // 1 mAh
  const double step_cap_sd = can::sig::kCapacitySd.factor / can::kMahPerAh;  // 0.1 mAh
  for (double sd : {0.0, step_sd, 5.1e-5, 6.5e-4}) {
    for (double cap : {0.0, 1.1, 2.3, 50.0}) {
      can::Uncertainty u;
      u.seq = 9;
      u.r_film_sd_ohm_m2 = sd;
      u.capacity_ah = cap;
      u.capacity_sd_ah = 0.0012;
      const can::Uncertainty r = round_trip(u);
      EXPECT_EQ(r.seq, 9);
      EXPECT_NEAR(r.r_film_sd_ohm_m2, sd, step_sd / 2 + 1e-18);
      EXPECT_NEAR(r.capacity_ah, cap, step_cap / 2 + 1e-12);
      EXPECT_NEAR(r.capacity_sd_ah, 0.0012, step_cap_sd / 2 + 1e-12);
    }
  }
  // None (NaN) is the largest raw value of each signal, where the receiver reads "none".
  can::Uncertainty none;
  none.r_film_sd_ohm_m2 = none.capacity_ah = none.capacity_sd_ah = std::nan("");
  const can::Uncertainty r = round_trip(none);
  EXPECT_DOUBLE_EQ(r.r_film_sd_ohm_m2, can::sig::kRFilmSd.max);
  EXPECT_DOUBLE_EQ(r.capacity_ah, can::sig::kCapacity.max / can::kMahPerAh);
  EXPECT_DOUBLE_EQ(r.capacity_sd_ah, can::sig::kCapacitySd.max / can::kMahPerAh);
}

TEST(RoundTrip, StatusAndRxStats) {
  for (std::uint32_t tick : {0u, 1u, 0xFFFFFFFFu}) {
    can::BmsStatus s;
    s.status_bits = 0xA5;
    s.fault_bits = 0xFF;
    s.tick_count = tick;
    const can::BmsStatus r = round_trip(s);
    EXPECT_EQ(r.status_bits, 0xA5);
    EXPECT_EQ(r.fault_bits, 0xFF);
    EXPECT_EQ(r.tick_count, tick);
  }
  can::BmsRxStats x;
  x.drop_length = 255;
  x.drop_crc = 1;
  x.drop_counter = 128;
  x.ignored_ids = 7;
  x.lost_frames = 254;
  x.ticks_without_meas = 3;
  const can::BmsRxStats y = round_trip(x);
  EXPECT_EQ(y.drop_length, 255);
  EXPECT_EQ(y.drop_crc, 1);
  EXPECT_EQ(y.drop_counter, 128);
  EXPECT_EQ(y.ignored_ids, 7);
  EXPECT_EQ(y.lost_frames, 254);
  EXPECT_EQ(y.ticks_without_meas, 3);
}

TEST(RoundTrip, DecodeRefusesOtherIdOrLength) {
  can::Measurement m;
  CanFrame f{};
  can::encode(m, 0, f);
  can::Control c;
  EXPECT_FALSE(can::decode(f, c));
  f.len = 7;
  EXPECT_FALSE(can::decode(f, m));
}

TEST(Transmitter, CountsPerMessageModulo16) {
  can::Transmitter tx;
  CanFrame f{};
  for (int k = 0; k < 20; ++k) {
    tx.encode(can::Measurement{}, f);
    EXPECT_EQ(can::frame_counter(f.data), k % 16);
  }
  tx.encode(can::Control{}, f);
  EXPECT_EQ(can::frame_counter(f.data), 0);
  EXPECT_EQ(tx.next_counter(can::Msg::measurement), 4);
}

TEST(Modes, NamesFollowTheContract) {
  EXPECT_STREQ(can::mode_name(can::Mode::rest), "rest");
  EXPECT_STREQ(can::mode_name(can::Mode::cc_discharge), "cc_discharge");
  EXPECT_STREQ(can::mode_name(can::Mode::cv_discharge), "cv_discharge");
  EXPECT_STREQ(can::mode_name(can::Mode::cc_charge), "cc_charge");
  EXPECT_STREQ(can::mode_name(can::Mode::cv_charge), "cv_charge");
  EXPECT_EQ(can::mode_from_raw(9), can::Mode::unknown);
}
