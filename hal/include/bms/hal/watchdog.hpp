// Watchdog: the application kicks it once per tick; a missed deadline resets the MCU (on
// target) or is reported (on Linux).
#pragma once

#include <cstdint>

namespace bms::hal {

class Watchdog {
 public:
  virtual void kick() = 0;
  /// The deadline between kicks, 0 when the watchdog does not enforce one.
  virtual std::uint32_t timeout_ms() const { return 0; }

 protected:
  Watchdog() = default;
  Watchdog(const Watchdog&) = default;
  Watchdog& operator=(const Watchdog&) = default;
  ~Watchdog() = default;
};

}  // namespace bms::hal
