// Lock-step mode: the simulator, not a timer, drives the tick. LockstepBus wraps the real
// CanBus and is at once the application's CanBus and its TickSource:
//
//   wait_next_tick() reads frames from the inner bus into a FIFO until a frame that the
//   classifier recognises as a tick trigger arrives (that frame is buffered too);
//   receive() then hands out exactly those frames, and reports Status::timeout when
//   they are used up, without reading ahead into the next tick's frames.
//
// So the frames processed in tick k are exactly those that arrived after tick k-1's
// trigger up to and including tick k's trigger: the run does not depend on timing.
// The application code is the same in both modes: wait_next_tick(); drain receive(); step.
// Portable (no heap); header-only.
#pragma once

#include <cstddef>
#include <cstdint>

#include "bms/hal/can_bus.hpp"
#include "bms/hal/frame_ring.hpp"
#include "bms/hal/tick_source.hpp"

namespace bms::hal {

/// Returns true when `frame` triggers a tick, and then stores the tick number in `tick`.
using TickClassifier = bool (*)(const CanFrame& frame, std::uint32_t& tick, void* ctx);

template <std::size_t Capacity = 32>
class LockstepBus final : public CanBus, public TickSource {
  static_assert(Capacity > 0, "LockstepBus needs room for at least the trigger frame");

 public:
  LockstepBus(CanBus& inner, TickClassifier classify, void* ctx = nullptr)
      : inner_(inner), classify_(classify), ctx_(ctx) {}

  /// A tick's answers are batched: the next wait_next_tick() sends them (flush) before it
  /// waits, and the host waits for them before it triggers the next tick, so nothing is late.
  Status send(const CanFrame& frame) override { return inner_.send_deferred(frame); }

  /// Hands out the frames buffered by wait_next_tick(); never waits (timeout_ms is
  /// ignored): an empty buffer gives Status::timeout.
  Status receive(CanFrame& frame, std::int32_t /*timeout_ms*/) override {
    return fifo_.pop(frame) ? Status::ok : Status::timeout;
  }

  Status set_filters(const CanFilter* filters, std::size_t count) override {
    return inner_.set_filters(filters, count);
  }

  const char* last_error() const override { return inner_.last_error(); }

  /// Reads the inner bus until a trigger frame arrives. timeout_ms bounds each wait for
  /// a frame (the host going silent), not the whole call.
  Status wait_next_tick(std::uint32_t& tick, std::int32_t timeout_ms) override {
    // A failed flush drops the frames, as a failed send would; the application never
    // acted on send's status either (the host sees the missing answer).
    (void)inner_.flush();
    for (;;) {
      CanFrame f{};
      const Status s = inner_.receive(f, timeout_ms);
      if (s != Status::ok) return s;
      if (fifo_.push_dropping_oldest(f)) ++overflowed_;  // keep the trigger that is coming
      std::uint32_t t = 0;
      if (classify_ != nullptr && classify_(f, t, ctx_)) {
        tick = t;
        ++ticks_;
        return Status::ok;
      }
    }
  }

  std::uint32_t ticks() const { return ticks_; }
  /// Frames lost because more than Capacity arrived before the application drained them.
  std::uint32_t overflowed_frames() const { return overflowed_; }
  std::size_t buffered() const { return fifo_.size(); }

 private:
  CanBus& inner_;
  TickClassifier classify_;
  void* ctx_;
  FrameRing<Capacity> fifo_;
  std::uint32_t ticks_ = 0;
  std::uint32_t overflowed_ = 0;
};

}  // namespace bms::hal
