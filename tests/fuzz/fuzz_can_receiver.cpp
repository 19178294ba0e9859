// Fuzz target: the CAN protocol codec and validating receiver (firmware/include/bms/fw/
// can_protocol.hpp), i.e. everything the BMS does with a frame from the bus.
//
// Input: byte 0 picks the node (bit 0: BMS or host receiver); then records of 12 bytes:
//   [flags] [id lo] [id hi] [len] [8 data bytes]
// flags bit 0: call on_tick() after the frame; bit 1: set the extended-id flag bit; bit 2:
// also encode the 8 data bytes as physical values (doubles, NaN and infinities included).
// len is taken mod 16, so lengths 9..15 (never valid on a classic bus) are tried too.
// Checked beyond "no crash, no UB": counters add up; an accepted frame decodes to what the
// receiver returned; decode -> encode -> decode is stable (no value drifts on re-encoding).
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#include "bms/fw/can/can_protocol.hpp"

namespace can = bms::fw::can;

namespace {

struct Frame {
  std::uint32_t id;
  std::uint8_t len;
  std::uint8_t data[8];
};

[[noreturn]] void fail() { std::abort(); }

bool same_bits(double a, double b) { return std::memcmp(&a, &b, sizeof a) == 0; }
bool same_bits(float a, float b) { return std::memcmp(&a, &b, sizeof a) == 0; }

bool equal(const can::Control& a, const can::Control& b) {
  return a.reset_estimator == b.reset_estimator && a.lockstep == b.lockstep && a.tick_trigger == b.tick_trigger &&
         a.tick == b.tick;
}
bool equal(const can::Measurement& a, const can::Measurement& b) {
  return a.seq == b.seq && same_bits(a.voltage_v, b.voltage_v) && same_bits(a.current_a, b.current_a);
}
bool equal(const can::Temperature& a, const can::Temperature& b) { return same_bits(a.temperature_k, b.temperature_k); }
bool equal(const can::Estimate1& a, const can::Estimate1& b) {
  return a.seq == b.seq && same_bits(a.r_film_ohm_m2, b.r_film_ohm_m2) && a.mode == b.mode &&
         a.rcsi_active == b.rcsi_active && a.valid == b.valid;
}
bool equal(const can::Estimate2& a, const can::Estimate2& b) { return a.seq == b.seq && same_bits(a.theta0, b.theta0); }
bool equal(const can::Estimate3& a, const can::Estimate3& b) { return a.seq == b.seq && same_bits(a.theta1, b.theta1); }
bool equal(const can::Health& a, const can::Health& b) {
  return a.seq == b.seq && same_bits(a.li_loss_ah, b.li_loss_ah) && same_bits(a.z_v, b.z_v);
}
bool equal(const can::Uncertainty& a, const can::Uncertainty& b) {
  return a.seq == b.seq && same_bits(a.r_film_sd_ohm_m2, b.r_film_sd_ohm_m2) && same_bits(a.capacity_ah, b.capacity_ah) &&
         same_bits(a.capacity_sd_ah, b.capacity_sd_ah);
}
bool equal(const can::BmsStatus& a, const can::BmsStatus& b) {
  return a.status_bits == b.status_bits && a.fault_bits == b.fault_bits && a.tick_count == b.tick_count;
}
bool equal(const can::BmsRxStats& a, const can::BmsRxStats& b) {
  return a.drop_length == b.drop_length && a.drop_crc == b.drop_crc && a.drop_counter == b.drop_counter &&
         a.ignored_ids == b.ignored_ids && a.lost_frames == b.lost_frames &&
         a.ticks_without_meas == b.ticks_without_meas;
}

// The receiver's decoded message must equal a plain decode of the frame, and re-encoding
// it (same counter) must decode to the same values and carry a good CRC.
template <class M>
void check_round_trip(const Frame& f, const M& from_receiver) {
  M m{};
  if (!can::decode(f, m)) fail();
  if (!equal(m, from_receiver)) fail();
  Frame again{};
  can::encode(m, can::frame_counter(f.data), again);
  if (!can::frame_crc_ok(again) || again.id != f.id || again.len != f.len) fail();
  M m2{};
  if (!can::decode(again, m2) || !equal(m, m2)) fail();
}

double as_double(const std::uint8_t* p) {
  double d = 0.0;
  std::memcpy(&d, p, sizeof d);
  return d;
}

// Encoders must take any double (NaN, infinities, huge values) without UB: they saturate.
void encode_physical(const std::uint8_t* p, std::uint8_t counter) {
  const double v = as_double(p);
  Frame f{};
  can::Measurement m;
  m.seq = static_cast<std::uint16_t>(counter * 331u);
  m.voltage_v = v;
  m.current_a = -v;
  can::encode(m, counter, f);
  can::Measurement back;
  if (!can::decode(f, back) || !(back.voltage_v >= 0.0) || !std::isfinite(back.current_a)) fail();
  can::Health h;
  h.li_loss_ah = v;
  h.z_v = v * 1e-3;
  can::encode(h, counter, f);
  can::Uncertainty u;
  u.r_film_sd_ohm_m2 = v * 1e-6;
  u.capacity_ah = v;
  u.capacity_sd_ah = v * 1e-3;
  can::encode(u, counter, f);
  can::Estimate1 e1;
  e1.r_film_ohm_m2 = v;
  can::encode(e1, counter, f);
  can::Estimate2 e2;
  e2.theta0 = static_cast<float>(std::isfinite(v) && std::fabs(v) < 3e38 ? v : 0.0);
  can::encode(e2, counter, f);
  can::Temperature t;
  t.temperature_k = v;
  can::encode(t, counter, f);
  can::decode(f, t);
  if (!std::isfinite(t.temperature_k)) fail();
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const can::Node self = (data[0] & 1u) != 0u ? can::Node::host : can::Node::bms;
  can::Receiver rx(self);
  can::LockstepTicks ticks;
  std::uint32_t fed = 0;
  constexpr std::size_t kRecord = 12;
  for (std::size_t at = 1; at + kRecord <= size; at += kRecord) {
    const std::uint8_t* r = data + at;
    Frame f{};
    f.id = static_cast<std::uint32_t>(r[1] | (r[2] << 8u));
    if ((r[0] & 2u) != 0u) f.id |= 0x80000000u;
    f.len = static_cast<std::uint8_t>(r[3] & 0x0Fu);
    std::memcpy(f.data, r + 4, 8);

    std::uint32_t tick = 0;
    ticks.classify(f, tick);
    can::RxMessage out;
    const can::RxResult res = rx.accept(f, out);
    ++fed;
    if (res == can::RxResult::accepted) {
      switch (out.msg) {
        case can::Msg::control: check_round_trip(f, out.control); break;
        case can::Msg::measurement: check_round_trip(f, out.measurement); break;
        case can::Msg::temperature: check_round_trip(f, out.temperature); break;
        case can::Msg::estimate1: check_round_trip(f, out.estimate1); break;
        case can::Msg::estimate2: check_round_trip(f, out.estimate2); break;
        case can::Msg::estimate3: check_round_trip(f, out.estimate3); break;
        case can::Msg::health: check_round_trip(f, out.health); break;
        case can::Msg::uncertainty: check_round_trip(f, out.uncertainty); break;
        case can::Msg::status: check_round_trip(f, out.status); break;
        case can::Msg::rx_stats: check_round_trip(f, out.rx_stats); break;
      }
      if (!can::frame_crc_ok(f)) fail();  // accepted implies a good CRC
    }
    (void)can::rx_result_name(res);
    if ((r[0] & 1u) != 0u) rx.on_tick();
    if ((r[0] & 4u) != 0u) encode_physical(r + 4, r[0]);
  }
  const can::RxCounters& c = rx.counters();
  if (c.accepted + c.ignored_id + c.dropped_total() != fed) fail();
  (void)rx.rx_stats();
  return 0;
}
