#include "bms/hal/fake/fake_time.hpp"

namespace bms::hal::fake {

ManualTickSource::ManualTickSource(ManualClock* clock, std::uint64_t period_ns)
    : clock_(clock), period_ns_(period_ns), origin_ns_(clock != nullptr ? clock->now_ns() : 0) {}

void ManualTickSource::overrun(std::uint32_t skipped) {
  next_tick_ += skipped;
  missed_ += skipped;
}

Status ManualTickSource::wait_next_tick(std::uint32_t& tick, std::int32_t /*timeout_ms*/) {
  if (pending_ == 0) return Status::timeout;
  --pending_;
  tick = next_tick_++;
  if (clock_ != nullptr) clock_->set_ns(origin_ns_ + static_cast<std::uint64_t>(tick) * period_ns_);
  return Status::ok;
}

}  // namespace bms::hal::fake
