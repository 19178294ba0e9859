// In-memory CAN bus for unit tests: two FakeCanBus objects connected with connect(a, b)
// form a pair (what a sends, b receives and vice versa); connect(a, a) is a loopback.
// Fault injection applies to the frames a bus sends, before they reach the peer.
// Host-only (uses the heap freely).
#pragma once

#include <cstddef>
#include <cstdint>
#include <deque>
#include <functional>
#include <string>
#include <vector>

#include "bms/hal/can_bus.hpp"

namespace bms::hal::fake {

class ManualClock;

/// What a fault hook does with a frame on its way to the peer.
enum class FaultAction : std::uint8_t { deliver, drop, duplicate };

/// Called for each sent frame (after the one-shot faults); may modify the frame.
using FaultHook = std::function<FaultAction(CanFrame& frame)>;

class FakeCanBus final : public CanBus {
 public:
  explicit FakeCanBus(std::size_t rx_capacity = 4096);
  ~FakeCanBus();
  FakeCanBus(const FakeCanBus&) = delete;
  FakeCanBus& operator=(const FakeCanBus&) = delete;

  /// Wire a and b together (a may be b: loopback). Replaces earlier connections.
  static void connect(FakeCanBus& a, FakeCanBus& b);
  void disconnect();

  Status send(const CanFrame& frame) override;
  /// Never blocks: with a linked clock, an empty receive with timeout_ms > 0 advances
  /// that clock by the timeout (time passes while nothing arrives).
  Status receive(CanFrame& frame, std::int32_t timeout_ms) override;
  Status set_filters(const CanFilter* filters, std::size_t count) override;
  const char* last_error() const override { return last_error_.c_str(); }

  // --- fault injection on transmit (in this order: send_status, one-shots, hook)
  /// Every send() returns `s` without delivering, until set back to Status::ok.
  void set_send_status(Status s) { send_status_ = s; }
  /// The next n sent frames are lost.
  void drop_next(std::size_t n = 1);
  /// The next sent frame has data[byte_index] ^= xor_mask (e.g. a bit error the CRC
  /// must catch).
  void corrupt_next(std::size_t byte_index, std::uint8_t xor_mask);
  /// The next sent frame arrives with this length (a DLC error).
  void truncate_next(std::uint8_t len);
  /// The next sent frame arrives twice (a repeated alive counter).
  void duplicate_next();
  void set_fault_hook(FaultHook hook) { hook_ = std::move(hook); }

  // --- direct injection and observation
  /// Put a frame into this bus's receive queue as if the peer had sent it (filters apply).
  Status inject(const CanFrame& frame);
  /// Every frame passed to send(), before faults.
  const std::vector<CanFrame>& sent() const { return sent_; }
  void clear_sent() { sent_.clear(); }
  std::size_t pending() const { return rx_.size(); }
  std::uint32_t rx_overflows() const { return rx_overflows_; }
  std::uint32_t filtered_out() const { return filtered_out_; }

  /// Receives with a timeout advance this clock when nothing is queued (may be nullptr).
  void set_clock(ManualClock* clock) { clock_ = clock; }

 private:
  enum class OneShot : std::uint8_t { drop, corrupt, truncate, duplicate };
  struct PendingFault {
    OneShot kind;
    std::size_t byte_index;
    std::uint8_t value;
  };
  Status deliver(const CanFrame& frame);
  bool passes_filters(std::uint32_t id) const;

  FakeCanBus* peer_ = nullptr;
  std::size_t rx_capacity_;
  std::deque<CanFrame> rx_;
  std::vector<CanFilter> filters_;
  bool accept_all_ = true;
  std::deque<PendingFault> faults_;
  FaultHook hook_;
  Status send_status_ = Status::ok;
  std::vector<CanFrame> sent_;
  std::uint32_t rx_overflows_ = 0;
  std::uint32_t filtered_out_ = 0;
  ManualClock* clock_ = nullptr;
  std::string last_error_;
};

}  // namespace bms::hal::fake
