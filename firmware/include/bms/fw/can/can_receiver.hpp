// The BMS CAN protocol's receiving side: validation of every frame (id, length, CRC,
// sequence window, alive counter) with counters and staleness (Receiver), and the
// recognition of the frames that trigger a lock-step tick (LockstepTicks).
//
// Header-only C++17: no heap, no exceptions, no RTTI; usable on a Cortex-M.
#pragma once

#include <cstddef>
#include <cstdint>

#include "bms/fw/can/can_codec.hpp"
#include "bms/fw/can/can_sequence.hpp"

namespace bms::fw::can {

// ---------------------------------------------------------------------------------------
// Receiver: validates and counts.

enum class RxResult : std::uint8_t {
  accepted,
  ignored_id,       ///< unknown id, or a message not addressed to this node: not an error
  dropped_length,   ///< known id with the wrong data length
  dropped_crc,      ///< CRC mismatch
  dropped_counter,  ///< alive counter repeated (frozen) or jumped backwards / too far
  dropped_seq,      ///< HOST_Measurement whose Seq lies outside the tick's window (stale, replayed, early)
};

constexpr const char* rx_result_name(RxResult r) {
  switch (r) {
    case RxResult::accepted: return "accepted";
    case RxResult::ignored_id: return "ignored_id";
    case RxResult::dropped_length: return "dropped_length";
    case RxResult::dropped_crc: return "dropped_crc";
    case RxResult::dropped_counter: return "dropped_counter";
    case RxResult::dropped_seq: return "dropped_seq";
  }
  return "unknown";
}

struct RxCounters {
  std::uint32_t accepted = 0;
  std::uint32_t ignored_id = 0;
  std::uint32_t dropped_length = 0;
  std::uint32_t dropped_crc = 0;
  std::uint32_t dropped_counter = 0;
  std::uint32_t dropped_seq = 0;   ///< measurements outside the sequence window (set_seq_window)
  std::uint32_t lost_frames = 0;   ///< frames inferred missing from accepted counter gaps
  std::uint32_t stale_events = 0;  ///< times the watched message became stale

  constexpr std::uint32_t dropped_total() const { return dropped_length + dropped_crc + dropped_counter + dropped_seq; }
};

/// The message decoded by Receiver::accept; only the member named by `msg` is set.
struct RxMessage {
  Msg msg = Msg::control;
  Control control;
  Measurement measurement;
  Temperature temperature;
  Estimate1 estimate1;
  Estimate2 estimate2;
  Estimate3 estimate3;
  Health health;
  Uncertainty uncertainty;
  BmsStatus status;
  BmsRxStats rx_stats;
};

/// Decode `data` into the member of `out` named by out.msg.
inline void unpack_message(const std::uint8_t* data, RxMessage& out) {
  switch (out.msg) {
    case Msg::control: unpack(data, out.control); break;
    case Msg::measurement: unpack(data, out.measurement); break;
    case Msg::temperature: unpack(data, out.temperature); break;
    case Msg::estimate1: unpack(data, out.estimate1); break;
    case Msg::estimate2: unpack(data, out.estimate2); break;
    case Msg::estimate3: unpack(data, out.estimate3); break;
    case Msg::health: unpack(data, out.health); break;
    case Msg::uncertainty: unpack(data, out.uncertainty); break;
    case Msg::status: unpack(data, out.status); break;
    case Msg::rx_stats: unpack(data, out.rx_stats); break;
  }
}

/// Largest accepted alive-counter step: 1 is the normal case, 2..7 mean 1..6 frames were
/// lost (accepted, counted in lost_frames); 0 (repeated/frozen) and 8..15 (old or
/// reordered frame) are dropped. After a drop for a step of 8..15 the receiver resyncs on
/// that counter, so a restarted sender costs one frame.
inline constexpr std::uint8_t kMaxCounterStep = 7;

/// The watched message is stale once it has been missing for more than this many ticks.
inline constexpr std::uint32_t kMaxMissingTicks = 2;

class Receiver {
 public:
  /// `self`: the node this receiver runs on; it accepts the messages addressed to it.
  /// The watched message (for staleness) is HOST_Measurement on the BMS, BMS_Status on
  /// the host.
  explicit Receiver(Node self = Node::bms)
      : self_(self), watched_(self == Node::bms ? Msg::measurement : Msg::status) {}

  /// Validate one frame: id (ignored when unknown or not for this node), length, CRC,
  /// alive counter, in that order; decode it into `out` when accepted.
  RxResult accept(std::uint32_t can_id, const std::uint8_t* data, std::uint8_t len, RxMessage& out) {
    const int idx = message_index(can_id);
    if (idx < 0 || kMessages[idx].receiver != self_) {
      ++counters_.ignored_id;
      return RxResult::ignored_id;
    }
    const MessageLayout& l = kMessages[idx];
    if (len != l.dlc) {
      ++counters_.dropped_length;
      return RxResult::dropped_length;
    }
    if (data[0] != frame_crc(can_id, data, len)) {
      ++counters_.dropped_crc;
      return RxResult::dropped_crc;
    }
    if (static_cast<Msg>(idx) == Msg::measurement && !seq_in_window(data)) {
      ++counters_.dropped_seq;
      last_rejected_seq_ = static_cast<std::uint16_t>(get_uint(data, sig::kSeq));
      return RxResult::dropped_seq;
    }
    const std::uint8_t c = frame_counter(data);
    CounterState& st = counter_state_[idx];
    if (st.seen) {
      const auto step = static_cast<std::uint8_t>((c - st.last) & kCounterMask);
      if (step == 0u) {
        ++counters_.dropped_counter;
        return RxResult::dropped_counter;
      }
      if (step > kMaxCounterStep) {
        st.last = c;  // resync
        ++counters_.dropped_counter;
        return RxResult::dropped_counter;
      }
      counters_.lost_frames += static_cast<std::uint32_t>(step - 1u);
    }
    st.seen = true;
    st.last = c;
    ++counters_.accepted;

    out.msg = static_cast<Msg>(idx);
    unpack_message(data, out);
    if (out.msg == watched_) {
      watched_seen_ = true;
      missing_ticks_ = 0;
    }
    return RxResult::accepted;
  }

  template <class FrameT>
  RxResult accept(const FrameT& frame, RxMessage& out) {
    return accept(frame.id, frame.data, frame.len, out);
  }

  /// Call once per tick, after the tick's frames were accepted: counts the ticks in a row
  /// without a valid watched message.
  void on_tick() {
    if (!watched_seen_ && missing_ticks_ < UINT32_MAX) {
      ++missing_ticks_;
      if (missing_ticks_ == kMaxMissingTicks + 1u) ++counters_.stale_events;
    }
    watched_seen_ = false;
  }

  /// Staleness counter: ticks in a row without a valid watched message (0 after one).
  std::uint32_t ticks_without_measurement() const { return missing_ticks_; }
  /// True once the watched message has been missing for more than kMaxMissingTicks
  /// ticks; false again as soon as a valid one is accepted.
  bool measurement_stale() const { return missing_ticks_ > kMaxMissingTicks; }

  const RxCounters& counters() const { return counters_; }

  /// The BMS_RxStats message for these counters (mod 256; staleness saturated).
  BmsRxStats rx_stats() const {
    BmsRxStats s;
    s.drop_length = static_cast<std::uint8_t>(counters_.dropped_length & 0xFFu);
    s.drop_crc = static_cast<std::uint8_t>(counters_.dropped_crc & 0xFFu);
    // DropCounter: alive-counter and sequence-window drops (both say "not this tick's frame").
    s.drop_counter = static_cast<std::uint8_t>((counters_.dropped_counter + counters_.dropped_seq) & 0xFFu);
    s.ignored_ids = static_cast<std::uint8_t>(counters_.ignored_id & 0xFFu);
    s.lost_frames = static_cast<std::uint8_t>(counters_.lost_frames & 0xFFu);
    s.ticks_without_meas = static_cast<std::uint8_t>(missing_ticks_ > 255u ? 255u : missing_ticks_);
    return s;
  }

  /// Forget counters, alive-counter history, staleness and the sequence window.
  void reset() { *this = Receiver(self_); }

  /// Sequence window of HOST_Measurement, set by the application before it drains a tick's
  /// frames: only Seq = first, first + 1, ..., first + count - 1 (mod 4096) passes; count 0
  /// lets none pass. The check comes before the alive counter's, so an old or replayed frame
  /// with a plausible counter is dropped (dropped_seq) without pushing the genuine frame out.
  void set_seq_window(std::uint16_t first, std::uint16_t count) {
    window_on_ = true;
    window_first_ = static_cast<std::uint16_t>(first & kSeqMask);
    window_count_ = count;
  }
  /// Every Seq passes (the default; the host side).
  void clear_seq_window() { window_on_ = false; }
  /// Seq of the last measurement dropped by the window (for the resynchronisation rule).
  std::uint16_t last_rejected_seq() const { return last_rejected_seq_; }

 private:
  struct CounterState {
    bool seen = false;
    std::uint8_t last = 0;
  };
  Node self_;
  Msg watched_;
  CounterState counter_state_[kMessageCount]{};
  RxCounters counters_{};
  bool seq_in_window(const std::uint8_t* data) const {
    if (!window_on_) return true;
    const auto seq = static_cast<std::uint32_t>(get_uint(data, sig::kSeq));
    return ((seq - window_first_) & kSeqMask) < window_count_;
  }

  bool watched_seen_ = false;
  std::uint32_t missing_ticks_ = 0;
  bool window_on_ = false;
  std::uint16_t window_first_ = 0;
  std::uint16_t window_count_ = 0;
  std::uint16_t last_rejected_seq_ = 0;
};

// ---------------------------------------------------------------------------------------
// Lock-step ticks

/// Recognises the frames that trigger a tick in lock-step mode, for bms::hal::LockstepBus.
/// Both trigger kinds carry the host's sequence number, followed by SeqTracker
/// (can_sequence.hpp) with a window of kMaxTickStep:
/// - HOST_Measurement, right length, good CRC: Seq (tick number mod 4096).
/// - HOST_Control, right length, good CRC, TickTrigger = 1: Tick mod 4096 (its full 32
///   bits only for the very first trigger, when there is nothing to compare with).
/// An adopted number triggers tick = the previous adopted tick + its distance (lost trigger
/// frames are missed ticks, at most kMaxTickStep - 1 per frame). A repeat or a number behind
/// (a duplicated, reordered or replayed frame) triggers nothing: running a tick for it would
/// step the model twice for one 0.2 s of cell time. A restarted host is followed after
/// SeqTracker::kResyncFrames consecutive frames; its first tick is the next one (no gap).
/// A HOST_Measurement with the right length but a bad CRC still triggers the next tick
/// (the host did send a tick; the Receiver then drops the frame, and the tick runs with the
/// measurement missing), but at most kMaxUnconfirmedTicks in a row: a burst of corrupted
/// copies cannot run the clock ahead of the genuine frames.
/// Use with LockstepBus through a captureless lambda:
///   [](const hal::CanFrame& f, uint32_t& t, void* c) {
///     return static_cast<can::LockstepTicks*>(c)->classify(f, t); }
class LockstepTicks {
 public:
  /// Largest tick step one trigger frame may claim (10 s of 0.2 s ticks).
  static constexpr std::uint32_t kMaxTickStep = 50;
  /// Ticks a corrupted trigger may run before a frame with a good CRC must come.
  static constexpr std::uint32_t kMaxUnconfirmedTicks = 1;

  template <class FrameT>
  bool classify(const FrameT& frame, std::uint32_t& tick) {
    if (frame.id == id::kMeasurement && frame.len == layout(Msg::measurement).dlc) {
      if (!frame_crc_ok(frame)) return on_corrupted(tick);
      const auto seq = static_cast<std::uint32_t>(get_uint(frame.data, sig::kSeq));
      return on_sequence(seq, seq, tick);
    }
    if (frame.id == id::kControl && frame.len == layout(Msg::control).dlc && frame_crc_ok(frame) &&
        get_uint(frame.data, sig::kCtlTickTrigger) != 0u) {
      const auto full = static_cast<std::uint32_t>(get_uint(frame.data, sig::kCtlTick));
      return on_sequence(full & kSeqMask, full, tick);
    }
    return false;
  }

  std::uint32_t last_tick() const { return last_tick_; }
  /// The Seq a measurement of the last triggered tick must carry; false when that tick was
  /// triggered by a corrupted frame (no measurement belongs to it).
  bool tick_seq(std::uint16_t& seq) const {
    seq = seq_.last();
    return have_ && !last_unconfirmed_;
  }
  /// Good trigger frames that triggered nothing (repeats, late, too far ahead, already run).
  std::uint32_t rejected() const { return rejected_; }
  /// Corrupted trigger frames beyond kMaxUnconfirmedTicks (triggered nothing).
  std::uint32_t unconfirmed_refused() const { return unconfirmed_refused_; }
  std::uint32_t resyncs() const { return seq_.resyncs(); }

 private:
  bool on_corrupted(std::uint32_t& tick) {
    if (!have_ || unconfirmed_ >= kMaxUnconfirmedTicks) {
      ++unconfirmed_refused_;
      return false;
    }
    ++unconfirmed_;
    last_unconfirmed_ = true;
    tick = ++last_tick_;
    return true;
  }

  bool on_sequence(std::uint32_t seq, std::uint32_t first_tick, std::uint32_t& tick) {
    switch (seq_.observe(static_cast<std::uint16_t>(seq), kMaxTickStep)) {
      case SeqTracker::Verdict::first: anchor_tick_ = first_tick; break;
      case SeqTracker::Verdict::in_window:
      case SeqTracker::Verdict::jump: anchor_tick_ += seq_.step(); break;
      case SeqTracker::Verdict::restart: anchor_tick_ = last_tick_ + 1u; break;
      case SeqTracker::Verdict::rejected: ++rejected_; return false;
    }
    // A tick already run on a corrupted trigger is not run again.
    if (have_ && static_cast<std::int32_t>(anchor_tick_ - last_tick_) <= 0) {
      ++rejected_;
      return false;
    }
    have_ = true;
    unconfirmed_ = 0;
    last_unconfirmed_ = false;
    last_tick_ = anchor_tick_;
    tick = last_tick_;
    return true;
  }

  SeqTracker seq_;
  bool have_ = false;
  bool last_unconfirmed_ = false;
  std::uint32_t unconfirmed_ = 0;
  std::uint32_t last_tick_ = 0;
  std::uint32_t anchor_tick_ = 0;  // the tick of the last adopted sequence number
  std::uint32_t rejected_ = 0;
  std::uint32_t unconfirmed_refused_ = 0;
};

}  // namespace bms::fw::can
