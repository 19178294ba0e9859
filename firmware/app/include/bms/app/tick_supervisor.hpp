// The tick's supervision (foxBMS style): the watchdog is kicked once per completed tick, and
// each tick's duration, measured on the HAL's monotonic clock from the moment the tick came
// to the moment its answer is ready, is held against its budget (by default the tick
// period). A tick over the budget raises the tick-overrun fault bit in that tick's
// BMS_Status and is counted; the bit clears at the next tick within the budget.
// Portable: no heap, no exceptions, no RTTI.
#pragma once

#include <cstdint>

#include "bms/hal/monotonic_clock.hpp"
#include "bms/hal/watchdog.hpp"

namespace bms::app {

class TickSupervisor {
 public:
  /// Both may be null (a test of the CAN and NVM path alone): no kick, no measurement.
  TickSupervisor(hal::Watchdog* watchdog, const hal::MonotonicClock* clock, std::uint64_t budget_ns)
      : watchdog_(watchdog), clock_(clock), budget_ns_(budget_ns) {}

  void tick_started() { start_ns_ = clock_ != nullptr ? clock_->now_ns() : 0u; }

  /// The tick's work is done: returns true when it took longer than the budget.
  bool over_budget() {
    if (clock_ == nullptr) return false;
    const std::uint64_t took_ns = clock_->now_ns() - start_ns_;
    if (took_ns > worst_ns_) worst_ns_ = took_ns;
    if (took_ns <= budget_ns_) return false;
    ++overruns_;
    return true;
  }

  /// The tick completed (its answer is on the bus).
  void tick_completed() {
    if (watchdog_ != nullptr) watchdog_->kick();
    ++kicks_;
  }

  std::uint32_t overruns() const { return overruns_; }
  std::uint32_t kicks() const { return kicks_; }
  std::uint64_t worst_tick_ns() const { return worst_ns_; }
  std::uint64_t budget_ns() const { return budget_ns_; }

 private:
  hal::Watchdog* watchdog_;
  const hal::MonotonicClock* clock_;
  std::uint64_t budget_ns_;
  std::uint64_t start_ns_ = 0;
  std::uint64_t worst_ns_ = 0;
  std::uint32_t overruns_ = 0;
  std::uint32_t kicks_ = 0;
};

}  // namespace bms::app
