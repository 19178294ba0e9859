#include "bms/hal/linux/linux_clock.hpp"

#include <ctime>

namespace bms::hal::lnx {

std::uint64_t LinuxMonotonicClock::now_ns() const {
  timespec ts{};
  ::clock_gettime(CLOCK_MONOTONIC, &ts);
  return static_cast<std::uint64_t>(ts.tv_sec) * 1'000'000'000u + static_cast<std::uint64_t>(ts.tv_nsec);
}

}  // namespace bms::hal::lnx
