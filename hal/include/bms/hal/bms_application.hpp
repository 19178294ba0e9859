// The firmware application: the glue between the HAL and the firmware core. Per tick:
// wait for the tick (timer, or the host's frame in lock-step), validate and decode the
// tick's frames (bms::fw::can::Receiver, with the tick's sequence window), run
// BmsCore::tick, send the estimate frames, and commit the core's state to non-volatile
// memory at the end of every constant-current charge and on a timer, both within the flash
// write budget (fw::nvm::WriteBudget).
// Portable: the Linux binary (hal/linux/app) and the board image use the same class.
// No heap, no exceptions, no RTTI.
#pragma once

#include <cmath>
#include <cstdint>

#include "bms/fw/bms_core.hpp"
#include "bms/fw/can_protocol.hpp"
#include "bms/fw/nvm_budget.hpp"
#include "bms/fw/nvm_store.hpp"
#include "bms/fw/state_schema.hpp"
#include "bms/hal/can_bus.hpp"
#include "bms/hal/log_sink.hpp"
#include "bms/hal/nvm.hpp"
#include "bms/hal/tick_source.hpp"

namespace bms::hal {

template <class Core>
class BmsApplication {
 public:
  // What survives a power cut: the core's state, the tick it belongs to (so that after a
  // restart in lock-step the firmware knows how many ticks it missed; the core then steps its
  // model over them, BmsCore::Config::catch_up_max_ticks) and the write budget's credit (a
  // power cycle must not refill it).
  struct Persisted {
    typename Core::State core;
    std::uint32_t tick;
    std::uint32_t budget_credit_ticks;
  };
  // The record's layout tag: the schema hash of every saved field (state_schema.hpp).
  static constexpr std::uint32_t kPersistedTag = [] {
    using P = Persisted;
    constexpr fw::schema::Field f[] = {BMS_SCHEMA_NESTED(P, core, Core), BMS_SCHEMA_FIELD(P, tick),
                                       BMS_SCHEMA_FIELD(P, budget_credit_ticks)};
    static_assert(fw::schema::covers(f, sizeof(P), alignof(P)), "Persisted changed: update its schema table");
    return fw::schema::hash("BmsApplication.Persisted", f, sizeof(P));
  }();
  using Store = fw::nvm::RecordStore<Persisted, kPersistedTag, NonVolatileMemory>;
  // Longest gap fed to the core as missed ticks (10 minutes); a longer one is a fresh start.
  static constexpr std::uint32_t kMaxMissedTicks = 3000u;
  // Real time: how many ticks a measurement's Seq may run ahead of the firmware's count of
  // ticks since the last one (the host's and the firmware's 0.2 s clocks jitter).
  static constexpr std::uint32_t kRealtimeSeqSlack = 2u;

  struct Options {
    bool lockstep = true;
    // Timer commits: at most one per this many ticks (0: none); each within the budget.
    std::uint32_t persist_every_ticks = 78910;  // the default budget's interval (4.4 h)
    bool persist_at_charge_end = true;          // commit when a CC charge ends (within the budget)
    fw::nvm::WriteBudgetConfig budget{};
    std::int32_t tick_timeout_ms = 1000;
    // Lock-step: the trigger rule the LockstepBus uses; the tick's measurement must carry
    // the Seq that triggered it. Null: no sequence check in lock-step.
    const fw::can::LockstepTicks* lockstep_ticks = nullptr;
  };

  struct NvmCounters {
    std::uint32_t commits = 0;
    std::uint32_t failures = 0;
    std::uint32_t refused_by_budget = 0;
  };

  BmsApplication(Core& core, CanBus& bus, TickSource& ticks, LogSink& log, NonVolatileMemory& nvm,
                 const Options& o)
      : core_(core), bus_(bus), ticks_(ticks), log_(log), o_(o), store_(nvm, 0), budget_(o.budget) {}

  // Restores the saved state if there is one; returns true if a state was restored.
  bool restore_from_nvm() {
    const fw::nvm::StoreStatus s = store_.load(image_);
    if (s == fw::nvm::StoreStatus::ok && core_.restore(image_.core)) {
      restored_ = true;
      rolled_back_ = store_.fell_back();
      budget_.restore_credit(image_.budget_credit_ticks);
      // Lock-step tick numbers restart from the host's 12-bit sequence number: the first tick
      // after the restart is compared modulo that. Real time has no common clock across a
      // restart, so the gap is unknown there.
      have_tick_ = o_.lockstep;
      tick_after_restart_ = o_.lockstep;
      last_tick_ = image_.tick;
      if (rolled_back_) {
        fault_bits_ |= fw::can::fault_bit::kNvm;
        log_.write(LogLevel::warning, "nvm: the newer slot is unreadable; restored the older state");
      } else {
        log_.write(LogLevel::info, "nvm: estimator state restored");
      }
      return true;
    }
    if (s != fw::nvm::StoreStatus::empty) {
      fault_bits_ |= fw::can::fault_bit::kNvm;
      log_.write(LogLevel::warning, "nvm: no valid saved state; starting fresh");
    }
    return false;
  }

  // Commits the state now if the write budget allows; true when committed. A refusal is not
  // a fault (the last commit stays); a failed commit sets the NVM fault bit, a good one
  // clears it.
  bool persist() {
    if (!budget_.try_spend()) {
      ++nvm_.refused_by_budget;
      return false;
    }
    image_.core = core_.save();
    image_.tick = last_tick_;
    image_.budget_credit_ticks = budget_.credit_ticks();
    const bool ok = store_.save(image_) == fw::nvm::StoreStatus::ok;
    if (ok) {
      ++nvm_.commits;
      fault_bits_ = static_cast<std::uint8_t>(fault_bits_ & ~fw::can::fault_bit::kNvm);
      since_persist_ = 0;
      save_pending_ = false;
    } else {
      ++nvm_.failures;
      fault_bits_ |= fw::can::fault_bit::kNvm;
    }
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
    budget_.tick(missed + 1u);
    ticks_since_sample_ = saturating_add(ticks_since_sample_, missed + 1u);
    last_tick_ = tick;
    have_tick_ = true;
    tick_after_restart_ = false;
    const fw::TickInput<double> in = receive_measurement();
    receiver_.on_tick();
    const auto out = core_.tick(in);
    last_ = out;
    send_outputs(out, receiver_.measurement_stale());
    schedule_commit(out.mode == fw::Mode::cc_charge, missed + 1u);
    return Status::ok;
  }

  const typename Core::Output& last_output() const { return last_; }
  const fw::can::Receiver& receiver() const { return receiver_; }
  std::uint32_t missed_ticks_total() const { return missed_total_; }
  const NvmCounters& nvm_counters() const { return nvm_; }
  const fw::nvm::WriteBudget& write_budget() const { return budget_; }
  const Store& store() const { return store_; }
  std::uint8_t fault_bits() const { return fault_bits_; }
  bool restored() const { return restored_; }
  bool rolled_back() const { return rolled_back_; }
  std::uint32_t last_tick() const { return last_tick_; }

 private:
  static std::uint32_t saturating_add(std::uint32_t a, std::uint32_t b) { return a + b < a ? 0xFFFFFFFFu : a + b; }

  std::uint32_t missed_ticks(std::uint32_t tick) const {
    if (!have_tick_) return 0u;
    std::uint32_t ahead = tick - last_tick_;
    if (tick_after_restart_) ahead &= fw::can::kSeqMask;
    if (ahead == 0u || ahead > kMaxMissedTicks) return 0u;
    return ahead - 1u;
  }

  // Lock-step: the LockstepBus hands out exactly this tick's frames, and the one measurement
  // that belongs to the tick carries the Seq that triggered it. Real time: drain what arrived
  // since the last tick; a measurement must be ahead of the last one by at most the ticks
  // since then (plus slack), and a host that restarted its Seq is followed after
  // SeqTracker::kResyncFrames consecutive frames.
  fw::TickInput<double> receive_measurement() {
    fw::TickInput<double> in{0.0, 0.0, false};
    open_seq_window();
    CanFrame f{};
    while (bus_.receive(f, kCanNoWait) == Status::ok) {
      fw::can::RxMessage m{};
      const fw::can::RxResult r = receiver_.accept(f, m);
      if (r == fw::can::RxResult::dropped_seq && !o_.lockstep) {
        if (rt_seq_.observe(receiver_.last_rejected_seq(), 0u) != fw::can::SeqTracker::Verdict::rejected)
          open_seq_window();
        continue;
      }
      if (r != fw::can::RxResult::accepted || m.msg != fw::can::Msg::measurement) continue;
      in = {m.measurement.voltage_v, m.measurement.current_a, true};
      seq_ = m.measurement.seq;
      ticks_since_sample_ = 0u;
      if (!o_.lockstep) {
        rt_seq_.observe(seq_, fw::can::kSeqHalfRange);
        open_seq_window();
      }
    }
    return in;
  }

  void open_seq_window() {
    if (o_.lockstep) {
      std::uint16_t seq = 0;
      if (o_.lockstep_ticks == nullptr) {
        receiver_.clear_seq_window();
      } else if (o_.lockstep_ticks->tick_seq(seq)) {
        receiver_.set_seq_window(seq, 1u);
      } else {
        receiver_.set_seq_window(0u, 0u);  // a tick triggered by a corrupted frame
      }
      return;
    }
    if (!rt_seq_.have()) {
      receiver_.clear_seq_window();
      return;
    }
    // Ticks since the last sample, the late ones (missed) included: the host kept sending.
    std::uint32_t span = saturating_add(ticks_since_sample_, kRealtimeSeqSlack);
    if (span < 1u) span = 1u;
    if (span > fw::can::kSeqHalfRange) span = fw::can::kSeqHalfRange;
    receiver_.set_seq_window(static_cast<std::uint16_t>(rt_seq_.last() + 1u), static_cast<std::uint16_t>(span));
  }

  // Commits requested by the end of a CC charge (the estimate just learned) or the timer stay
  // pending until the write budget allows them.
  void schedule_commit(bool cc_charge, std::uint32_t ticks) {
    if (o_.persist_at_charge_end && was_cc_charge_ && !cc_charge) save_pending_ = true;
    was_cc_charge_ = cc_charge;
    since_persist_ = saturating_add(since_persist_, ticks);
    if (o_.persist_every_ticks != 0u && since_persist_ >= o_.persist_every_ticks) save_pending_ = true;
    if (save_pending_ && budget_.credit_ticks() >= budget_.interval_ticks()) persist();
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
                                               (restored_ ? can::status_bit::kNvmRestored : 0u) |
                                               (rolled_back_ ? can::status_bit::kNvmRolledBack : 0u));
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
  fw::nvm::WriteBudget budget_;
  NvmCounters nvm_{};
  Persisted image_{};  // save/restore buffer: a member, not a stack object (it is large)
  fw::can::Receiver receiver_{fw::can::Node::bms};
  fw::can::SeqTracker rt_seq_;  // real time: the host's sequence as last accepted
  fw::can::Transmitter tx_;
  typename Core::Output last_{};
  std::uint16_t seq_ = 0;
  std::uint32_t since_persist_ = 0;
  std::uint32_t ticks_since_sample_ = 0;
  std::uint32_t dropped_seen_ = 0;
  std::uint8_t fault_bits_ = 0;
  bool save_pending_ = false;
  bool was_cc_charge_ = false;
  bool restored_ = false;
  bool rolled_back_ = false;
  bool have_tick_ = false;
  bool tick_after_restart_ = false;
  std::uint32_t last_tick_ = 0;
  std::uint32_t missed_total_ = 0;
};

}  // namespace bms::hal
