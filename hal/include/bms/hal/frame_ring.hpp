// A fixed ring of CAN frames, first in first out: the queue behind MemoryCanBus (a full ring
// refuses the frame) and LockstepBus (a full ring drops its oldest frame to keep the trigger
// that is coming). Portable: no heap; header-only.
#pragma once

#include <cstddef>

#include "bms/hal/can_bus.hpp"

namespace bms::hal {

template <std::size_t Capacity>
class FrameRing {
  static_assert(Capacity > 0, "a ring needs room for one frame");

 public:
  /// False (and nothing stored) when the ring is full.
  bool push(const CanFrame& f) {
    if (count_ == Capacity) return false;
    ring_[(head_ + count_) % Capacity] = f;
    ++count_;
    return true;
  }
  /// Stores f, dropping the oldest frame when the ring is full; true when one was dropped.
  bool push_dropping_oldest(const CanFrame& f) {
    const bool full = count_ == Capacity;
    if (full) {
      head_ = (head_ + 1u) % Capacity;
      --count_;
    }
    push(f);
    return full;
  }
  /// False when the ring is empty.
  bool pop(CanFrame& f) {
    if (count_ == 0u) return false;
    f = ring_[head_];
    head_ = (head_ + 1u) % Capacity;
    --count_;
    return true;
  }
  std::size_t size() const { return count_; }

 private:
  CanFrame ring_[Capacity]{};
  std::size_t head_ = 0;
  std::size_t count_ = 0;
};

}  // namespace bms::hal
