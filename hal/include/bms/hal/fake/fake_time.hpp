// Manual clock and tick source for unit tests: time moves only when the test says so.
#pragma once

#include <cstdint>

#include "bms/hal/monotonic_clock.hpp"
#include "bms/hal/tick_source.hpp"

namespace bms::hal::fake {

class ManualClock final : public MonotonicClock {
 public:
  explicit ManualClock(std::uint64_t start_ns = 0) : now_ns_(start_ns) {}
  std::uint64_t now_ns() const override { return now_ns_; }
  void advance_ns(std::uint64_t dt_ns) { now_ns_ += dt_ns; }
  /// Sets the time; a value in the past is ignored (the clock is monotonic).
  void set_ns(std::uint64_t t_ns) {
    if (t_ns > now_ns_) now_ns_ = t_ns;
  }

 private:
  std::uint64_t now_ns_;
};

/// Ticks are queued with fire(); wait_next_tick() takes one or reports Status::timeout
/// (it never blocks). With a linked clock, each tick taken sets the clock to
/// first_tick_ns + tick * period.
class ManualTickSource final : public TickSource {
 public:
  explicit ManualTickSource(ManualClock* clock = nullptr, std::uint64_t period_ns = kTickPeriodNs);

  /// Make n more ticks due.
  void fire(std::uint32_t n = 1) { pending_ += n; }
  /// Simulate an overrun: the next tick taken comes `skipped` numbers later, and the
  /// skipped ticks are counted in missed_ticks().
  void overrun(std::uint32_t skipped);

  Status wait_next_tick(std::uint32_t& tick, std::int32_t timeout_ms) override;
  std::uint64_t period_ns() const override { return period_ns_; }
  std::uint32_t missed_ticks() const override { return missed_; }
  std::uint32_t pending() const { return pending_; }

 private:
  ManualClock* clock_;
  std::uint64_t period_ns_;
  std::uint64_t origin_ns_;
  std::uint32_t pending_ = 0;
  std::uint32_t next_tick_ = 0;
  std::uint32_t missed_ = 0;
};

}  // namespace bms::hal::fake
