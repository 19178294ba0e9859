// Following the host's 12-bit tick sequence number (HOST_Measurement.Seq, HOST_Control.Tick
// mod 4096) across lost frames, stale or replayed frames, long gaps and a restarted host.
//
// The rule, in one place for the lock-step trigger (LockstepTicks) and the real-time
// measurement window (BmsApplication):
// - The first sequence number seen is adopted.
// - A number 1..max_ahead steps ahead of the last adopted one is adopted at once: the
//   normal case (1) and lost frames (2..max_ahead). max_ahead bounds what one frame can
//   claim, so one frame cannot ask the core to catch up over more than max_ahead - 1 ticks.
// - Anything else (a repeat, a number behind, or too far ahead) is rejected. Rejected
//   numbers are watched: kResyncFrames of them in a row with consecutive values (s, s+1,
//   s+2) are a host that restarted or came back after a long gap, and the last of them is
//   adopted: as a forward jump when it lies at most half the sequence range ahead (the gap
//   is then known), otherwise as a restart (one step: the gap is unknown).
// A CRC-valid frame is not authenticated: a sender that can forge consecutive frames can
// still move the sequence, but never by more than half the range (2047 ticks) at once.
//
// Header-only C++17: no heap, no exceptions, no RTTI.
#pragma once

#include <cstdint>

namespace bms::fw::can {

inline constexpr std::uint16_t kSeqMask = 0x0FFF;
/// Largest step a forward jump may have: half the 12-bit range, so "ahead" stays unambiguous.
inline constexpr std::uint32_t kSeqHalfRange = kSeqMask / 2u;

class SeqTracker {
 public:
  static constexpr std::uint8_t kResyncFrames = 3;

  enum class Verdict : std::uint8_t {
    first,      ///< nothing adopted before: adopted
    in_window,  ///< 1..max_ahead ahead: adopted, step() = the distance
    jump,       ///< confirmed forward jump beyond max_ahead: adopted, step() = the distance
    restart,    ///< confirmed restart (the sequence went back): adopted, step() = 1
    rejected,   ///< repeat, behind or too far ahead: not adopted (a resync candidate)
  };

  Verdict observe(std::uint16_t seq_raw, std::uint32_t max_ahead) {
    const auto seq = static_cast<std::uint16_t>(seq_raw & kSeqMask);
    if (!have_) {
      adopt(seq, 0u);
      return Verdict::first;
    }
    const std::uint32_t ahead = static_cast<std::uint32_t>(seq - last_) & kSeqMask;
    if (ahead >= 1u && ahead <= max_ahead && ahead <= kSeqHalfRange) {
      adopt(seq, ahead);
      return Verdict::in_window;
    }
    run_ = (run_ > 0u && seq == ((candidate_ + 1u) & kSeqMask)) ? static_cast<std::uint8_t>(run_ + 1u) : 1u;
    candidate_ = seq;
    if (run_ < kResyncFrames) return Verdict::rejected;
    ++resyncs_;
    const bool forward = ahead >= 1u && ahead <= kSeqHalfRange;
    adopt(seq, forward ? ahead : 1u);
    return forward ? Verdict::jump : Verdict::restart;
  }

  bool have() const { return have_; }
  std::uint16_t last() const { return last_; }
  /// Distance of the last adoption (0 for the first).
  std::uint32_t step() const { return step_; }
  /// Confirmed jumps and restarts so far.
  std::uint32_t resyncs() const { return resyncs_; }
  void reset() { *this = SeqTracker{}; }

 private:
  void adopt(std::uint16_t seq, std::uint32_t step) {
    have_ = true;
    last_ = seq;
    step_ = step;
    run_ = 0u;
  }

  bool have_ = false;
  std::uint16_t last_ = 0;
  std::uint32_t step_ = 0;
  std::uint8_t run_ = 0;
  std::uint16_t candidate_ = 0;
  std::uint32_t resyncs_ = 0;
};

}  // namespace bms::fw::can
