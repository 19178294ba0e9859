// The BMS CAN protocol's transmitter: one alive counter per message, frames encoded by the
// codec (can_codec.hpp).
//
// Header-only C++17: no heap, no exceptions, no RTTI; usable on a Cortex-M.
#pragma once

#include <cstddef>
#include <cstdint>

#include "bms/fw/can/can_codec.hpp"

namespace bms::fw::can {

/// Keeps one alive counter per message and encodes frames with it.
class Transmitter {
 public:
  template <class M, class FrameT>
  void encode(const M& m, FrameT& frame) {
    auto& c = counters_[static_cast<std::size_t>(MessageTraits<M>::kMsg)];
    can::encode(m, c, frame);
    c = static_cast<std::uint8_t>((c + 1u) & kCounterMask);
  }
  std::uint8_t next_counter(Msg m) const { return counters_[static_cast<std::size_t>(m)]; }
  void reset() {
    for (auto& c : counters_) c = 0;
  }

 private:
  std::uint8_t counters_[kMessageCount]{};
};

}  // namespace bms::fw::can
