// Watchdog for unit tests: counts the kicks.
#pragma once

#include <cstdint>

#include "bms/hal/watchdog.hpp"

namespace bms::hal::fake {

class CountingWatchdog final : public Watchdog {
 public:
  void kick() override { ++kicks_; }
  std::uint32_t kicks() const { return kicks_; }

 private:
  std::uint32_t kicks_ = 0;
};

}  // namespace bms::hal::fake
