// CLOCK_MONOTONIC.
#pragma once

#include <cstdint>

#include "bms/hal/monotonic_clock.hpp"

namespace bms::hal::lnx {

class LinuxMonotonicClock final : public MonotonicClock {
 public:
  std::uint64_t now_ns() const override;
};

}  // namespace bms::hal::lnx
