// CAN bus interface: classic CAN frames (at most 8 data bytes), send, receive without
// blocking or with a timeout, acceptance filters. Portable: no heap, no exceptions, no RTTI.
#pragma once

#include <cstddef>
#include <cstdint>

#include "bms/hal/status.hpp"

namespace bms::hal {

/// A classic CAN data frame. `id` is an 11-bit identifier unless kCanIdExtended is set,
/// in which case the low 29 bits are the identifier. Remote and error frames are not
/// represented (backends never deliver them).
struct CanFrame {
  std::uint32_t id;
  std::uint8_t len;      ///< data length code, 0..8
  std::uint8_t data[8];  ///< bytes beyond `len` are unspecified
};

inline constexpr std::uint32_t kCanIdExtended = 0x80000000u;  ///< flag bit, like Linux CAN_EFF_FLAG
inline constexpr std::uint32_t kCanStdIdMask = 0x7FFu;
inline constexpr std::uint32_t kCanExtIdMask = 0x1FFFFFFFu;
inline constexpr std::uint8_t kCanMaxLen = 8;

/// True when the frame can be put on a classic CAN bus as it is.
constexpr bool can_frame_valid(const CanFrame& f) {
  if (f.len > kCanMaxLen) return false;
  if ((f.id & kCanIdExtended) != 0u) return (f.id & ~(kCanIdExtended | kCanExtIdMask)) == 0u;
  return (f.id & ~kCanStdIdMask) == 0u;
}

/// Acceptance filter: a received frame passes when (frame.id & mask) == (id & mask).
/// The kCanIdExtended bit takes part in the comparison when it is set in `mask`.
struct CanFilter {
  std::uint32_t id;
  std::uint32_t mask;
};

/// True when `frame_id` passes filter `f`.
constexpr bool can_filter_match(const CanFilter& f, std::uint32_t frame_id) {
  return (frame_id & f.mask) == (f.id & f.mask);
}

/// Filter that passes exactly one standard identifier.
constexpr CanFilter can_filter_exact(std::uint32_t std_id) {
  return CanFilter{std_id & kCanStdIdMask, kCanStdIdMask | kCanIdExtended};
}

inline constexpr std::size_t kCanMaxFilters = 16;

/// Receive timeouts, in milliseconds.
inline constexpr std::int32_t kCanNoWait = 0;        ///< poll: return Status::timeout at once if empty
inline constexpr std::int32_t kCanWaitForever = -1;  ///< block until a frame arrives

class CanBus {
 public:
  /// Queue one frame for transmission. invalid_argument for a frame that fails
  /// can_frame_valid(); overflow when the transmit queue is full; io_error otherwise.
  virtual Status send(const CanFrame& frame) = 0;

  /// Queue one frame to go out at the next flush(), with the others queued, where the
  /// driver can send a batch at once (the per-frame system call is what a Linux process
  /// pays for); the default sends it now. Errors as send(), possibly reported by flush().
  virtual Status send_deferred(const CanFrame& frame) { return send(frame); }

  /// Send the frames queued by send_deferred(), in order. A failure drops the rest.
  virtual Status flush() { return Status::ok; }

  /// Take the next received frame that passed the filters. timeout_ms: kCanNoWait (0)
  /// polls, kCanWaitForever (<0) blocks, >0 waits at most that long. Status::timeout
  /// when nothing arrived.
  virtual Status receive(CanFrame& frame, std::int32_t timeout_ms) = 0;

  /// Replace the acceptance filters: a frame is delivered when it passes any of them.
  /// count == 0 delivers nothing; after opening, everything is delivered (as if one
  /// filter {0, 0} were set). count > kCanMaxFilters: invalid_argument.
  virtual Status set_filters(const CanFilter* filters, std::size_t count) = 0;

  /// Human-readable reason for the last failure, "" when there was none.
  virtual const char* last_error() const { return ""; }

  /// Non-blocking receive.
  Status try_receive(CanFrame& frame) { return receive(frame, kCanNoWait); }

 protected:
  CanBus() = default;
  CanBus(const CanBus&) = default;
  CanBus& operator=(const CanBus&) = default;
  ~CanBus() = default;  // not virtual: no deleting destructor, no operator delete on target
};

}  // namespace bms::hal
