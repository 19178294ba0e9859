// Real-time tick source: a periodic timerfd on CLOCK_MONOTONIC.
#pragma once

#include <cstdint>

#include "bms/hal/tick_source.hpp"

namespace bms::hal::lnx {

class TimerfdTickSource final : public TickSource {
 public:
  TimerfdTickSource() = default;
  ~TimerfdTickSource();
  TimerfdTickSource(const TimerfdTickSource&) = delete;
  TimerfdTickSource& operator=(const TimerfdTickSource&) = delete;

  /// Start the timer: the first tick (number 0) comes one period from now.
  Status open(std::uint64_t period_ns = kTickPeriodNs);
  void close();

  Status wait_next_tick(std::uint32_t& tick, std::int32_t timeout_ms) override;
  std::uint64_t period_ns() const override { return period_ns_; }
  std::uint32_t missed_ticks() const override { return missed_; }
  const char* last_error() const override { return error_; }

 private:
  Status fail(Status s, const char* what, int err);
  int fd_ = -1;
  std::uint64_t period_ns_ = kTickPeriodNs;
  std::uint64_t expirations_ = 0;
  std::uint32_t missed_ = 0;
  char error_[160] = "";
};

}  // namespace bms::hal::lnx
