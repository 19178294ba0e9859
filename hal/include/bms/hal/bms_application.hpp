// The firmware application: the glue between the HAL and the firmware core. Per tick:
// wait for the tick (timer, or the host's frame in lock-step), validate and decode the
// tick's frames (bms::fw::can::Receiver), run BmsCore::tick, send the estimate frames,
// and persist the core's state to non-volatile memory every `persist_every_ticks`.
// Portable: the Linux binary (hal/linux/app) and the board image use the same class.
// No heap, no exceptions, no RTTI.
#pragma once

#include <cstdint>

#include "bms/fw/bms_core.hpp"
#include "bms/fw/can_protocol.hpp"
#include "bms/fw/nvm_store.hpp"
#include "bms/hal/can_bus.hpp"
#include "bms/hal/log_sink.hpp"
#include "bms/hal/nvm.hpp"
#include "bms/hal/tick_source.hpp"

namespace bms::hal {

template <class Core>
class BmsApplication {
 public:
  // What survives a power cut: the core's state and the tick it belongs to, so that after a
  // restart in lock-step the firmware knows how many ticks it missed (the core then steps its
  // model over them, BmsCore::Config::catch_up_max_ticks).
  struct Persisted {
    typename Core::State core;
    std::uint32_t tick;
    std::uint32_t reserved;
  };
  static constexpr std::uint32_t kPersistedTag =
      (0x41u << 24) | (static_cast<std::uint32_t>(sizeof(Persisted) & 0xFFFFu) << 8) |
      (Core::kLayoutTag & 0xFFu);
  using Store = fw::nvm::RecordStore<Persisted, kPersistedTag, NonVolatileMemory>;
  // Longest gap fed to the core as missed ticks (10 minutes); a longer one is a new start.
  static constexpr std::uint32_t kMaxMissedTicks = 3000u;

  struct Options {
    bool lockstep = true;
    std::uint32_t persist_every_ticks = 300;  // one minute of 0.2 s ticks
    std::int32_t tick_timeout_ms = 1000;
  };

  BmsApplication(Core& core, CanBus& bus, TickSource& ticks, LogSink& log, NonVolatileMemory& nvm,
                 const Options& o)
      : core_(core), bus_(bus), ticks_(ticks), log_(log), o_(o), store_(nvm, 0) {}

  // Restores the saved state if there is one; returns true if a state was restored.
  bool restore_from_nvm() {
    const fw::nvm::StoreStatus s = store_.load(image_);
    if (s == fw::nvm::StoreStatus::ok && core_.restore(image_.core)) {
      restored_ = true;
      // Lock-step tick numbers restart from the host's 12-bit sequence number: the first tick
      // after the restart is compared modulo that. Real time has no common clock across a
      // restart, so the gap is unknown there.
      have_tick_ = o_.lockstep;
      tick_after_restart_ = o_.lockstep;
      last_tick_ = image_.tick;
      log_.write(LogLevel::info, "nvm: estimator state restored");
      return true;
    }
    if (s != fw::nvm::StoreStatus::empty) {
      fault_bits_ |= fw::can::fault_bit::kNvm;
      log_.write(LogLevel::warning, "nvm: no valid saved state; starting fresh");
    }
    return false;
  }

  bool persist() {
    image_.core = core_.save();
    image_.tick = last_tick_;
    image_.reserved = 0u;
    const bool ok = store_.save(image_) == fw::nvm::StoreStatus::ok;
    if (!ok) fault_bits_ |= fw::can::fault_bit::kNvm;
    return ok;
  }

  // One tick. Returns Status::timeout when no tick came within the timeout (the caller
  // decides whether to stop), or the bus error.
  Status step() {
    std::uint32_t tick = 0;
    const Status ws = ticks_.wait_next_tick(tick, o_.tick_timeout_ms);
    if (ws != Status::ok) return ws;
    // Ticks that came and went without reaching this loop (lock-step: frames lost on the bus,
    // the bus down, the process dead; real time: a late process) are ticks without a sample.
    const std::uint32_t missed = missed_ticks(tick);
    core_.ticks_missed(missed);
    missed_total_ += missed;
    last_tick_ = tick;
    have_tick_ = true;
    tick_after_restart_ = false;
    fw::TickInput<double> in{0.0, 0.0, false};
    CanFrame f{};
    // Lock-step: the LockstepBus hands out exactly this tick's frames. Real time: drain
    // what arrived since the last tick.
    while (bus_.receive(f, kCanNoWait) == Status::ok) {
      fw::can::RxMessage m{};
      if (receiver_.accept(f, m) != fw::can::RxResult::accepted) continue;
      if (m.msg == fw::can::Msg::measurement) {
        in = {m.measurement.voltage_v, m.measurement.current_a, true};
        seq_ = m.measurement.seq;
      }
    }
    receiver_.on_tick();
    const auto out = core_.tick(in);
    last_ = out;
    send_outputs(out, receiver_.measurement_stale());
    if (o_.persist_every_ticks != 0u && ++since_persist_ >= o_.persist_every_ticks) {
      since_persist_ = 0;
      persist();
    }
    return Status::ok;
  }

  const typename Core::Output& last_output() const { return last_; }
  const fw::can::Receiver& receiver() const { return receiver_; }
  std::uint32_t missed_ticks_total() const { return missed_total_; }

 private:
  std::uint32_t missed_ticks(std::uint32_t tick) const {
    if (!have_tick_) return 0u;
    std::uint32_t ahead = tick - last_tick_;
    if (tick_after_restart_) ahead &= fw::can::kSeqMask;
    if (ahead == 0u || ahead > kMaxMissedTicks) return 0u;
    return ahead - 1u;
  }

  void send_outputs(const typename Core::Output& out, bool stale) {
    namespace can = fw::can;
    CanFrame f{};
    can::Estimate1 e1;
    e1.seq = seq_;
    e1.r_film_ohm_m2 = out.r_film_est_ohm_m2;
    e1.mode = out.mode;
    e1.rcsi_active = out.rcsi_active;
    e1.valid = std::isfinite(out.r_film_est_ohm_m2);
    tx_.encode(e1, f);
    bus_.send(f);
    can::Estimate2 e2;
    e2.seq = seq_;
    e2.theta0 = static_cast<float>(out.theta[0]);
    tx_.encode(e2, f);
    bus_.send(f);
    can::Estimate3 e3;
    e3.seq = seq_;
    e3.theta1 = static_cast<float>(out.theta[1]);
    tx_.encode(e3, f);
    bus_.send(f);
    can::Health h;
    h.seq = seq_;
    h.li_loss_ah = out.li_loss_ah;
    h.z_v = out.z_v;
    tx_.encode(h, f);
    bus_.send(f);
    tx_.encode(receiver_.rx_stats(), f);
    bus_.send(f);
    // Status last: the host takes it as the end of this tick's answer.
    can::BmsStatus st;
    st.status_bits = static_cast<std::uint8_t>(can::status_bit::kRunning |
                                               (out.rcsi_active ? can::status_bit::kRcsiActive : 0u) |
                                               (o_.lockstep ? can::status_bit::kLockstep : 0u) |
                                               (stale ? can::status_bit::kMeasStale : 0u) |
                                               (std::isfinite(out.r_film_est_ohm_m2) ? can::status_bit::kEstimateValid : 0u) |
                                               (restored_ ? can::status_bit::kNvmRestored : 0u));
    std::uint8_t faults = fault_bits_;
    if (stale) faults |= can::fault_bit::kMeasStale;
    if (fw::has_status(out.status, fw::FwStatus::kVoltageOutOfRange)) faults |= can::fault_bit::kVoltageRange;
    if (fw::has_status(out.status, fw::FwStatus::kCurrentImplausible)) faults |= can::fault_bit::kCurrentRange;
    if ((out.status & (fw::bit(fw::FwStatus::kModelInvalid) | fw::bit(fw::FwStatus::kPredictionNonFinite) |
                       fw::bit(fw::FwStatus::kThetaRestored))) != 0u)
      faults |= can::fault_bit::kEstimator;
    if (receiver_.counters().dropped_total() != dropped_seen_) {
      faults |= can::fault_bit::kRxDropped;
      dropped_seen_ = receiver_.counters().dropped_total();
    }
    st.fault_bits = faults;
    st.tick_count = out.tick;
    tx_.encode(st, f);
    bus_.send(f);
  }

  Core& core_;
  CanBus& bus_;
  TickSource& ticks_;
  LogSink& log_;
  Options o_;
  Store store_;
  Persisted image_{};  // save/restore buffer: a member, not a stack object (it is large)
  fw::can::Receiver receiver_{fw::can::Node::bms};
  fw::can::Transmitter tx_;
  typename Core::Output last_{};
  std::uint16_t seq_ = 0;
  std::uint32_t since_persist_ = 0;
  std::uint32_t dropped_seen_ = 0;
  std::uint8_t fault_bits_ = 0;
  bool restored_ = false;
  bool have_tick_ = false;
  bool tick_after_restart_ = false;
  std::uint32_t last_tick_ = 0;
  std::uint32_t missed_total_ = 0;
};

}  // namespace bms::hal
