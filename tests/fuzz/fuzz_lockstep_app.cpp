// Fuzz target: the lock-step trigger rule (can::LockstepTicks), the LockstepBus that cuts the
// bus into ticks, and BmsApplication (the sequence window, missed ticks, the receiver, the
// answer frames, NVM commits) fed with any stream of host frames. A small stand-in core
// records every tick's input, so the application layer is what is explored.
//
// Input: byte 0: bit 0 lock-step (1) or real time (0); bit 1 fix the CRC of every frame
// (so the fields behind it are reached). Then records of 11 bytes:
//   [kind] [b0..b9]
// kind % 4: 0 HOST_Measurement (b0..b1 Seq, b2 counter, b3..b4 voltage raw), 1 HOST_Control
// (b0..b3 Tick, b4 TickTrigger, b5 counter), 2 raw frame (b0..b1 id, b2 len, b3..b9 data),
// 3 end of a real-time tick (the timer fires). kind bit 7: corrupt the frame after the CRC.
// Checked beyond "no crash, no UB":
// - one frame never makes the core catch up over more than LockstepTicks::kMaxTickStep - 1
//   ticks, and a confirmed resynchronisation over at most half the Seq range;
// - a tick's measurement carries that tick's Seq (the BMS_Estimate1 Seq sent equals the
//   trigger's), and no tick runs on an empty window with a measurement;
// - every tick answers with exactly six frames, BMS_Status last.
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "bms/fw/can/can_protocol.hpp"
#include "bms/fw/nvm/state_schema.hpp"
#include "bms/app/bms_application.hpp"
#include "bms/hal/lockstep.hpp"

namespace can = bms::fw::can;
namespace fw = bms::fw;
namespace hal = bms::hal;

namespace fuzz_app {

struct Core {
  struct State {
    double level_v;
    std::uint32_t ticks;
  };
  using Output = fw::TickOutput<double, 1>;
  Output tick(const fw::TickInput<double>& in) {
    last = in;
    ++ticks;
    Output o{};
    o.mode = (ticks / 7u) % 2u == 0u ? fw::Mode::cc_charge : fw::Mode::rest;
    o.r_film_est_ohm_m2 = 1e-3;
    o.tick = ticks;
    return o;
  }
  void ticks_missed(std::uint32_t n) { missed_now += n; }
  State save() const { return State{last.voltage_v, ticks}; }
  bool restore(const State&) { return true; }
  fw::TickInput<double> last{};
  std::uint32_t ticks = 0;
  std::uint32_t missed_now = 0;
};

constexpr std::uint32_t state_schema(fw::schema::Type<Core>) {
  using St = Core::State;
  constexpr fw::schema::Field f[] = {BMS_SCHEMA_FIELD(St, level_v), BMS_SCHEMA_FIELD(St, ticks)};
  return fw::schema::hash("FuzzCore.State", f, sizeof(St));
}

}  // namespace fuzz_app

namespace {

[[noreturn]] void fail() { std::abort(); }

class QueueBus final : public hal::CanBus {
 public:
  hal::Status send(const hal::CanFrame& f) override {
    sent.push_back(f);
    return hal::Status::ok;
  }
  hal::Status receive(hal::CanFrame& f, std::int32_t) override {
    if (head == rx.size()) return hal::Status::timeout;
    f = rx[head++];
    return hal::Status::ok;
  }
  hal::Status set_filters(const hal::CanFilter*, std::size_t) override { return hal::Status::ok; }
  std::vector<hal::CanFrame> rx, sent;
  std::size_t head = 0;
};

class Timer final : public hal::TickSource {
 public:
  hal::Status wait_next_tick(std::uint32_t& tick, std::int32_t) override {
    if (pending == 0) return hal::Status::timeout;
    --pending;
    tick = next++;
    return hal::Status::ok;
  }
  std::uint32_t pending = 0, next = 0;
};

class MemNvm final : public hal::NonVolatileMemory {
 public:
  std::size_t size_bytes() const override { return sizeof mem; }
  std::size_t page_size() const override { return 64; }
  hal::Status read(std::size_t o, void* d, std::size_t n) override {
    if (!span_fits(o, n, sizeof mem)) return hal::Status::out_of_range;
    std::memcpy(d, mem + o, n);
    return hal::Status::ok;
  }
  hal::Status write(std::size_t o, const void* s, std::size_t n) override {
    if (!span_fits(o, n, sizeof mem)) return hal::Status::out_of_range;
    std::memcpy(mem + o, s, n);
    return hal::Status::ok;
  }
  hal::Status erase(std::size_t o, std::size_t n) override {
    if (!span_fits(o, n, sizeof mem)) return hal::Status::out_of_range;
    std::memset(mem + o, 0xFF, n);
    return hal::Status::ok;
  }
  std::uint8_t mem[1024];
  MemNvm() { std::memset(mem, 0xFF, sizeof mem); }
};

class NullLog final : public hal::LogSink {
 public:
  void write(hal::LogLevel, const char*) override {}
};

using App = bms::app::BmsApplication<fuzz_app::Core>;

hal::CanFrame make_frame(const std::uint8_t* r, bool fix_crc) {
  hal::CanFrame f{};
  const std::uint8_t kind = r[0] & 3u;
  const std::uint8_t* b = r + 1;
  if (kind == 0) {
    can::Measurement m;
    m.seq = static_cast<std::uint16_t>(b[0] | (b[1] << 8));
    m.voltage_v = (b[3] | (b[4] << 8)) * 1e-4;
    can::encode(m, b[2], f);
  } else if (kind == 1) {
    can::Control c;
    c.tick = static_cast<std::uint32_t>(b[0]) | (static_cast<std::uint32_t>(b[1]) << 8) |
             (static_cast<std::uint32_t>(b[2]) << 16) | (static_cast<std::uint32_t>(b[3]) << 24);
    c.tick_trigger = (b[4] & 1u) != 0u;
    can::encode(c, b[5], f);
  } else {
    f.id = static_cast<std::uint32_t>(b[0] | ((b[1] & 7u) << 8));
    f.len = static_cast<std::uint8_t>(b[2] % 9u);
    std::memcpy(f.data + 1, b + 3, 7);
    if (fix_crc && f.len > 0) f.data[0] = can::frame_crc(f.id, f.data, f.len);
  }
  if ((r[0] & 0x80u) != 0u) f.data[3] ^= 0x5A;
  return f;
}

// The frames the application sent for its last tick: seven (BMS_Estimate1-3, BMS_Health,
// BMS_Uncertainty, BMS_RxStats), BMS_Status last; returns the Seq of BMS_Estimate1.
std::uint16_t check_answer(const QueueBus& bus, std::size_t from) {
  if (bus.sent.size() - from != 7u || bus.sent.back().id != can::id::kStatus) fail();
  can::Estimate1 e1;
  if (!can::decode(bus.sent[from], e1)) fail();
  return e1.seq;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const bool lockstep = (data[0] & 1u) != 0u;
  const bool fix_crc = (data[0] & 2u) != 0u;
  static QueueBus bus;
  static Timer timer;
  static MemNvm nvm;
  static NullLog log;
  bus = QueueBus{};
  timer = Timer{};
  nvm = MemNvm{};
  can::LockstepTicks rule;
  hal::LockstepBus<64> lbus(bus, [](const hal::CanFrame& f, std::uint32_t& t, void* c) {
    return static_cast<can::LockstepTicks*>(c)->classify(f, t);
  }, &rule);
  fuzz_app::Core core;
  App::Options o;
  o.lockstep = lockstep;
  o.lockstep_ticks = &rule;
  o.persist_every_ticks = 5;
  o.tick_timeout_ms = 0;
  hal::CanBus& app_bus = lockstep ? static_cast<hal::CanBus&>(lbus) : bus;
  hal::TickSource& app_ticks = lockstep ? static_cast<hal::TickSource&>(lbus) : timer;
  App app(core, app_bus, app_ticks, log, nvm, o);
  app.restore_from_nvm();
  auto step_all = [&]() {
    for (;;) {
      const std::uint32_t resyncs = rule.resyncs();
      const std::size_t sent = bus.sent.size();
      core.missed_now = 0;
      if (app.step() != hal::Status::ok) return;
      const bool resynced = rule.resyncs() != resyncs;
      const std::uint32_t bound = lockstep && !resynced ? can::LockstepTicks::kMaxTickStep - 1u : can::kSeqHalfRange;
      if (lockstep && core.missed_now > bound) fail();
      const std::uint16_t seq = check_answer(bus, sent);
      std::uint16_t expected = 0;
      if (lockstep && core.last.present) {
        if (!rule.tick_seq(expected) || seq != expected) fail();
      }
    }
  };
  for (std::size_t i = 1; i + 11 <= size; i += 11) {
    const std::uint8_t* r = data + i;
    if (!lockstep && (r[0] & 3u) == 3u) {
      timer.pending = 1;
      step_all();
      continue;
    }
    bus.rx.push_back(make_frame(r, fix_crc));
    if (lockstep) step_all();
  }
  timer.pending = 1;
  step_all();
  return 0;
}
