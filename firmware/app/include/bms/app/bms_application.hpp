// The firmware application: the glue between the HAL and the firmware core. One tick
// (step()):
//   1. wait for the tick (timer, or the host's frame in lock-step) and count missed ticks;
//   2. validate and decode the tick's frames (fw::can::Receiver, with the tick's sequence
//      window): the measurement, the host's Control (ResetEstimator) and HOST_Temperature;
//   3. run BmsCore::tick (after a requested reset, from the power-on state);
//   4. send the estimate frames, BMS_Status last, with the fault bits of this tick (the
//      tick-overrun bit from the tick's measured duration, TickSupervisor);
//   5. commit the core's state to non-volatile memory when a CC charge ended or the timer
//      asks, within the flash write budget (StatePersistence);
//   6. kick the watchdog.
// Portable: the Linux binary (apps/linux) and the board image run this same class.
// No heap, no exceptions, no RTTI.
#pragma once

#include <cmath>
#include <cstdint>
#include <type_traits>

#include "bms/app/state_persistence.hpp"
#include "bms/app/tick_supervisor.hpp"
#include "bms/fw/estimation/bms_core.hpp"
#include "bms/fw/can/can_protocol.hpp"
#include "bms/fw/model/paper_cell.hpp"
#include "bms/hal/can_bus.hpp"
#include "bms/hal/log_sink.hpp"
#include "bms/hal/monotonic_clock.hpp"
#include "bms/hal/nvm.hpp"
#include "bms/hal/tick_source.hpp"
#include "bms/hal/watchdog.hpp"

namespace bms::app {

template <class Core>
class BmsApplication {
 public:
  using Persistence = StatePersistence<Core>;
  // The core's number type (float on a single-precision FPU): the bus's values are doubles.
  using CoreScalar = std::remove_cv_t<decltype(Core::Output::r_film_est_ohm_m2)>;
  using Persisted = typename Persistence::Persisted;
  using Store = typename Persistence::Store;
  static constexpr std::uint32_t kPersistedTag = Persistence::kPersistedTag;
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
    // Supervision: kicked once per completed tick, and the clock the tick's duration is
    // measured on. Null: none (tests of the CAN and NVM path alone).
    hal::Watchdog* watchdog = nullptr;
    const hal::MonotonicClock* clock = nullptr;
    // A tick's time budget; 0: the tick source's period.
    std::uint64_t tick_budget_ns = 0;
  };

  using NvmCounters = typename Persistence::Counters;

  BmsApplication(Core& core, hal::CanBus& bus, hal::TickSource& ticks, hal::LogSink& log,
                 hal::NonVolatileMemory& nvm, const Options& o)
      : core_(core),
        bus_(bus),
        ticks_(ticks),
        log_(log),
        o_(o),
        nvm_(core, nvm, {o.persist_every_ticks, o.persist_at_charge_end, o.budget}),
        supervisor_(o.watchdog, o.clock, o.tick_budget_ns != 0u ? o.tick_budget_ns : ticks.period_ns()),
        power_on_(core.save()) {}

  // Restores the saved state if there is one; returns true if a state was restored.
  bool restore_from_nvm() {
    std::uint32_t tick = 0;
    const typename Persistence::Loaded l = nvm_.restore(tick);
    if (l == Persistence::Loaded::restored || l == Persistence::Loaded::rolled_back) {
      restored_ = true;
      rolled_back_ = l == Persistence::Loaded::rolled_back;
      // Lock-step tick numbers restart from the host's 12-bit sequence number: the first tick
      // after the restart is compared modulo that. Real time has no common clock across a
      // restart, so the gap is unknown there.
      have_tick_ = o_.lockstep;
      tick_after_restart_ = o_.lockstep;
      last_tick_ = tick;
      if (rolled_back_) {
        log_.write(hal::LogLevel::warning, "nvm: the newer slot is unreadable; restored the older state");
      } else {
        log_.write(hal::LogLevel::info, "nvm: estimator state restored");
      }
      return true;
    }
    if (l == Persistence::Loaded::unreadable) log_.write(hal::LogLevel::warning, "nvm: no valid saved state; starting fresh");
    return false;
  }

  // Commits the state now if the write budget allows; true when committed.
  bool persist() { return nvm_.commit(last_tick_); }

  // One tick. Returns Status::timeout when no tick came within the timeout (the caller
  // decides whether to stop), or the bus error.
  hal::Status step() {
    std::uint32_t tick = 0;
    const hal::Status ws = ticks_.wait_next_tick(tick, o_.tick_timeout_ms);
    if (ws != hal::Status::ok) return ws;
    supervisor_.tick_started();
    // Ticks that came and went without reaching this loop (lock-step: frames lost on the bus,
    // the bus down, the process dead; real time: a late process) are ticks without a sample.
    const std::uint32_t missed = missed_ticks(tick);
    core_.ticks_missed(missed);
    missed_total_ += missed;
    ticks_since_sample_ = saturating_add(ticks_since_sample_, missed + 1u);
    last_tick_ = tick;
    have_tick_ = true;
    tick_after_restart_ = false;
    const fw::TickInput<double> in = receive_frames();
    receiver_.on_tick();
    if (reset_requested_) reset_estimator();
    const auto out =
        core_.tick({CoreScalar(in.voltage_v), CoreScalar(in.current_a), in.present, CoreScalar(temperature_k_)});
    last_ = out;
    // Real time: a tick the timer skipped is an overrun of the tick before it.
    const bool late = !o_.lockstep && missed > 0u;
    send_outputs(out, receiver_.measurement_stale(), late);
    nvm_.after_tick(out.mode == fw::Mode::cc_charge, missed + 1u, last_tick_);
    supervisor_.tick_completed();
    return hal::Status::ok;
  }

  const typename Core::Output& last_output() const { return last_; }
  const fw::can::Receiver& receiver() const { return receiver_; }
  std::uint32_t missed_ticks_total() const { return missed_total_; }
  const NvmCounters& nvm_counters() const { return nvm_.counters(); }
  const fw::nvm::WriteBudget& write_budget() const { return nvm_.write_budget(); }
  const Store& store() const { return nvm_.store(); }
  const TickSupervisor& supervisor() const { return supervisor_; }
  std::uint32_t clock_mismatches() const { return clock_mismatches_; }
  // The fault bits that outlast a tick (NVM, internal); BMS_Status adds the tick's own.
  std::uint8_t fault_bits() const {
    return static_cast<std::uint8_t>((nvm_.failed() ? fw::can::fault_bit::kNvm : 0u) | latched_faults_);
  }
  std::uint8_t last_status_fault_bits() const { return last_faults_; }
  bool restored() const { return restored_; }
  bool rolled_back() const { return rolled_back_; }
  std::uint32_t last_tick() const { return last_tick_; }
  std::uint32_t resets() const { return resets_; }
  std::uint32_t send_failures() const { return send_failures_; }

 private:
  static std::uint32_t saturating_add(std::uint32_t a, std::uint32_t b) { return a + b < a ? 0xFFFFFFFFu : a + b; }

  std::uint32_t missed_ticks(std::uint32_t tick) const {
    if (!have_tick_) return 0u;
    std::uint32_t ahead = tick - last_tick_;
    if (tick_after_restart_) ahead &= fw::can::kSeqMask;
    if (ahead == 0u || ahead > kMaxMissedTicks) return 0u;
    return ahead - 1u;
  }

  // The host's ResetEstimator (a service tool after a cell replacement): the core goes back
  // to its power-on state, whose commit is asked for so that a power cycle does not bring the
  // forgotten state back.
  void reset_estimator() {
    reset_requested_ = false;
    if (!core_.restore(power_on_)) {
      latched_faults_ |= fw::can::fault_bit::kInternal;
      log_.write(hal::LogLevel::error, "reset: the power-on state was rejected");
      return;
    }
    ++resets_;
    nvm_.request_commit();
    log_.write(hal::LogLevel::info, "reset: estimator back to its power-on state");
  }

  // Lock-step: the LockstepBus hands out exactly this tick's frames, and the one measurement
  // that belongs to the tick carries the Seq that triggered it. Real time: drain what arrived
  // since the last tick; a measurement must be ahead of the last one by at most the ticks
  // since then (plus slack), and a host that restarted its Seq is followed after
  // SeqTracker::kResyncFrames consecutive frames.
  fw::TickInput<double> receive_frames() {
    fw::TickInput<double> in{0.0, 0.0, false};
    open_seq_window();
    hal::CanFrame f{};
    while (bus_.receive(f, hal::kCanNoWait) == hal::Status::ok) {
      fw::can::RxMessage m{};
      const fw::can::RxResult r = receiver_.accept(f, m);
      if (r == fw::can::RxResult::dropped_seq && !o_.lockstep) {
        if (rt_seq_.observe(receiver_.last_rejected_seq(), 0u) != fw::can::SeqTracker::Verdict::rejected)
          open_seq_window();
        continue;
      }
      if (r != fw::can::RxResult::accepted) continue;
      if (m.msg == fw::can::Msg::control) on_control(m.control);
      if (m.msg == fw::can::Msg::temperature) on_temperature(m.temperature.temperature_k);
      if (m.msg != fw::can::Msg::measurement) continue;
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

  // A host that believes the other side drives the ticks is misconfigured (its frames would
  // trigger nothing, or ticks would run twice): counted, and the tick reports an internal fault.
  void on_control(const fw::can::Control& c) {
    if (c.reset_estimator) reset_requested_ = true;
    if (c.lockstep != o_.lockstep) ++clock_mismatches_;
  }

  // The last HOST_Temperature goes to the core with every measurement (the model's properties
  // follow it); one the model refuses (outside its range) makes the estimate not valid.
  void on_temperature(double temperature_k) { temperature_k_ = temperature_k; }

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

  void send(const hal::CanFrame& f) {
    if (bus_.send(f) != hal::Status::ok) ++send_failures_;
  }

  void send_outputs(const typename Core::Output& out, bool stale, bool late) {
    namespace can = fw::can;
    const bool valid = std::isfinite(out.r_film_est_ohm_m2) && !outside_model_temperature(out);
    hal::CanFrame f{};
    can::Estimate1 e1;
    e1.seq = seq_;
    e1.r_film_ohm_m2 = out.r_film_est_ohm_m2;
    e1.mode = out.mode;
    e1.rcsi_active = out.rcsi_active;
    e1.valid = valid;
    tx_.encode(e1, f);
    send(f);
    can::Estimate2 e2;
    e2.seq = seq_;
    e2.theta0 = static_cast<float>(out.theta[0]);
    tx_.encode(e2, f);
    send(f);
    can::Estimate3 e3;
    e3.seq = seq_;
    e3.theta1 = static_cast<float>(out.theta[1]);
    tx_.encode(e3, f);
    send(f);
    can::Health h;
    h.seq = seq_;
    h.li_loss_ah = out.li_loss_ah;
    h.z_v = out.z_v;
    tx_.encode(h, f);
    send(f);
    can::Uncertainty u;
    u.seq = seq_;
    // The largest raw value means none (NaN): a saturated estimate is sent one step under it.
    u.r_film_sd_ohm_m2 = can::below_none(out.r_film_sd_ohm_m2, can::sig::kRFilmSd);
    u.capacity_ah = can::below_none(out.capacity_ah, can::sig::kCapacity);
    u.capacity_sd_ah = can::below_none(out.capacity_sd_ah, can::sig::kCapacitySd);
    tx_.encode(u, f);
    send(f);
    tx_.encode(receiver_.rx_stats(), f);
    send(f);
    // Status last: the host takes it as the end of this tick's answer.
    can::BmsStatus st;
    st.status_bits = status_bits(out, stale, valid);
    const bool overrun = supervisor_.over_budget() || late;
    st.fault_bits = tick_faults(out, stale, overrun);
    last_faults_ = st.fault_bits;
    st.tick_count = out.tick;
    tx_.encode(st, f);
    send(f);
  }

  static bool outside_model_temperature(const typename Core::Output& out) {
    return fw::has_status(out.status, fw::FwStatus::kTemperatureImplausible);
  }

  std::uint8_t status_bits(const typename Core::Output& out, bool stale, bool valid) const {
    namespace sb = fw::can::status_bit;
    return static_cast<std::uint8_t>(sb::kRunning | (out.rcsi_active ? sb::kRcsiActive : 0u) |
                                     (o_.lockstep ? sb::kLockstep : 0u) | (stale ? sb::kMeasStale : 0u) |
                                     (valid ? sb::kEstimateValid : 0u) | (restored_ ? sb::kNvmRestored : 0u) |
                                     (rolled_back_ ? sb::kNvmRolledBack : 0u));
  }

  // Estimator: the core rejected a non-finite state or prediction, or the cell is outside
  // the model's temperature. Internal: the core reports a call-order violation or a bad
  // configuration (a firmware defect, not a cell or bus condition), a frame could not be
  // sent, or a reset was refused.
  std::uint8_t tick_faults(const typename Core::Output& out, bool stale, bool overrun) {
    namespace can = fw::can;
    std::uint8_t faults = fault_bits();
    if (stale) faults |= can::fault_bit::kMeasStale;
    if (fw::has_status(out.status, fw::FwStatus::kVoltageOutOfRange)) faults |= can::fault_bit::kVoltageRange;
    if (fw::has_status(out.status, fw::FwStatus::kCurrentImplausible)) faults |= can::fault_bit::kCurrentRange;
    constexpr fw::StatusWord kEstimatorFaults = fw::bit(fw::FwStatus::kModelInvalid) |
                                                fw::bit(fw::FwStatus::kPredictionNonFinite) |
                                                fw::bit(fw::FwStatus::kThetaRestored);
    if ((out.status & kEstimatorFaults) != 0u || outside_model_temperature(out)) faults |= can::fault_bit::kEstimator;
    constexpr fw::StatusWord kInternalFaults = fw::bit(fw::FwStatus::kCallOrder) | fw::bit(fw::FwStatus::kConfigInvalid);
    if ((out.status & kInternalFaults) != 0u || send_failures_ != send_failures_seen_ ||
        clock_mismatches_ != clock_mismatches_seen_)
      faults |= can::fault_bit::kInternal;
    send_failures_seen_ = send_failures_;
    clock_mismatches_seen_ = clock_mismatches_;
    if (overrun) faults |= can::fault_bit::kTickOverrun;
    if (receiver_.counters().dropped_total() != dropped_seen_) {
      faults |= can::fault_bit::kRxDropped;
      dropped_seen_ = receiver_.counters().dropped_total();
    }
    return faults;
  }

  Core& core_;
  hal::CanBus& bus_;
  hal::TickSource& ticks_;
  hal::LogSink& log_;
  Options o_;
  Persistence nvm_;
  TickSupervisor supervisor_;
  typename Core::State power_on_;  // what ResetEstimator goes back to
  fw::can::Receiver receiver_{fw::can::Node::bms};
  fw::can::SeqTracker rt_seq_;  // real time: the host's sequence as last accepted
  fw::can::Transmitter tx_;
  typename Core::Output last_{};
  std::uint16_t seq_ = 0;
  std::uint32_t ticks_since_sample_ = 0;
  std::uint32_t dropped_seen_ = 0;
  std::uint32_t send_failures_ = 0;
  std::uint32_t send_failures_seen_ = 0;
  std::uint32_t resets_ = 0;
  std::uint32_t clock_mismatches_ = 0;  // Control frames whose Lockstep bit is not this firmware's mode
  std::uint32_t clock_mismatches_seen_ = 0;
  std::uint8_t latched_faults_ = 0;
  std::uint8_t last_faults_ = 0;
  bool reset_requested_ = false;
  double temperature_k_ = 0.0;  // the last HOST_Temperature; 0: none yet
  bool restored_ = false;
  bool rolled_back_ = false;
  bool have_tick_ = false;
  bool tick_after_restart_ = false;
  std::uint32_t last_tick_ = 0;
  std::uint32_t missed_total_ = 0;
};

}  // namespace bms::app
