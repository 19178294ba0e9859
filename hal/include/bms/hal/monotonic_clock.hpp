// A clock that never goes backwards, in nanoseconds from an unspecified origin.
#pragma once

#include <cstdint>

namespace bms::hal {

class MonotonicClock {
 public:
  virtual std::uint64_t now_ns() const = 0;

 protected:
  MonotonicClock() = default;
  MonotonicClock(const MonotonicClock&) = default;
  MonotonicClock& operator=(const MonotonicClock&) = default;
  ~MonotonicClock() = default;
};

}  // namespace bms::hal
