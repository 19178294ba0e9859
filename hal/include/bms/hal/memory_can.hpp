// A CAN bus in memory, for boards without a CAN controller the emulator models (QEMU's MPS2)
// and for host tests: two MemoryCanBus objects connected with connect(a, b) form a pair
// (what a sends, b receives and vice versa); connect(a, a) is a loopback. Each bus queues the
// frames it has received in a fixed ring; a full ring refuses the frame (Status::overflow,
// counted). Filters are not modelled (every frame passes). Portable: no heap; header-only.
#pragma once

#include <cstddef>
#include <cstdint>

#include "bms/hal/can_bus.hpp"
#include "bms/hal/frame_ring.hpp"

namespace bms::hal {

template <std::size_t Capacity = 16>
class MemoryCanBus final : public CanBus {
  static_assert(Capacity > 0, "a bus needs room for one frame");

 public:
  static void connect(MemoryCanBus& a, MemoryCanBus& b) {
    a.peer_ = &b;
    b.peer_ = &a;
  }

  Status send(const CanFrame& frame) override {
    if (peer_ == nullptr) return Status::not_open;
    if (frame.len > 8u) return Status::invalid_argument;
    if (!peer_->ring_.push(frame)) {
      ++refused_;
      return Status::overflow;
    }
    ++sent_;
    return Status::ok;
  }

  /// Never waits: the sender runs in the same thread, so waiting could not help.
  Status receive(CanFrame& frame, std::int32_t /*timeout_ms*/) override {
    return ring_.pop(frame) ? Status::ok : Status::timeout;
  }

  Status set_filters(const CanFilter* /*filters*/, std::size_t /*count*/) override { return Status::ok; }

  std::uint32_t sent() const { return sent_; }
  std::uint32_t refused() const { return refused_; }
  std::size_t queued() const { return ring_.size(); }

 private:
  MemoryCanBus* peer_ = nullptr;
  FrameRing<Capacity> ring_;
  std::uint32_t sent_ = 0;
  std::uint32_t refused_ = 0;
};

}  // namespace bms::hal
