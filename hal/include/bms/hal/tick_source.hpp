// The estimator's sample clock: one tick every 0.2 s. In real-time mode a hardware or OS
// timer drives it; in lock-step mode the simulator's frames drive it (see lockstep.hpp),
// so a run is deterministic and may go faster than real time.
#pragma once

#include <cstdint>

#include "bms/hal/status.hpp"

namespace bms::hal {

inline constexpr std::uint64_t kTickPeriodNs = 200'000'000u;  ///< 0.2 s, the paper's T

class TickSource {
 public:
  /// Wait for the next tick. On Status::ok, `tick` is the tick's number (the first tick
  /// is 0 for timer sources; in lock-step mode the number the simulator sent). When the
  /// caller was late and several periods elapsed, real-time sources return the latest
  /// tick number (ticks are skipped, and counted in missed_ticks()).
  /// timeout_ms: 0 polls, < 0 waits forever, > 0 waits at most that long -> Status::timeout.
  virtual Status wait_next_tick(std::uint32_t& tick, std::int32_t timeout_ms) = 0;

  /// Nominal period in nanoseconds.
  virtual std::uint64_t period_ns() const { return kTickPeriodNs; }

  /// Ticks that elapsed without the caller waiting for them (overruns).
  virtual std::uint32_t missed_ticks() const { return 0; }

  virtual const char* last_error() const { return ""; }

 protected:
  TickSource() = default;
  TickSource(const TickSource&) = default;
  TickSource& operator=(const TickSource&) = default;
  ~TickSource() = default;
};

}  // namespace bms::hal
