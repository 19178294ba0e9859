// The Linux process has no hardware watchdog to arm: a supervisor (systemd's WatchdogSec,
// the HIL host's timeouts) watches the process from outside. This one counts the kicks and
// keeps the last kick's time, so a stall shows in the exit counters.
#pragma once

#include <cstdint>

#include "bms/hal/linux/linux_clock.hpp"
#include "bms/hal/watchdog.hpp"

namespace bms::hal::lnx {

class ProcessWatchdog final : public Watchdog {
 public:
  void kick() override {
    ++kicks_;
    last_kick_ns_ = clock_.now_ns();
  }
  std::uint32_t kicks() const { return kicks_; }
  std::uint64_t last_kick_ns() const { return last_kick_ns_; }

 private:
  LinuxMonotonicClock clock_;
  std::uint32_t kicks_ = 0;
  std::uint64_t last_kick_ns_ = 0;
};

}  // namespace bms::hal::lnx
