// Log sink writing "[   12.345678] warning: message" lines to stderr (one write() per
// line, so lines from several threads or processes do not interleave), and a watchdog
// that only reports late kicks through a log sink (no reset on Linux).
#pragma once

#include <cstdint>

#include "bms/hal/log_sink.hpp"
#include "bms/hal/monotonic_clock.hpp"
#include "bms/hal/watchdog.hpp"

namespace bms::hal::lnx {

class StderrLogSink final : public LogSink {
 public:
  /// Messages below `min_level` are discarded. With a clock, each line starts with the
  /// clock's time in seconds.
  explicit StderrLogSink(LogLevel min_level = LogLevel::info, const MonotonicClock* clock = nullptr,
                         int fd = 2)
      : min_level_(min_level), clock_(clock), fd_(fd) {}
  void write(LogLevel level, const char* message) override;
  void set_min_level(LogLevel l) { min_level_ = l; }

 private:
  LogLevel min_level_;
  const MonotonicClock* clock_;
  int fd_;
};

/// kick() checks the time since the previous kick; a gap over timeout_ms is logged as a
/// warning and counted. timeout_ms == 0: a no-op watchdog.
class LoggingWatchdog final : public Watchdog {
 public:
  LoggingWatchdog(const MonotonicClock& clock, std::uint32_t timeout_ms, LogSink* log)
      : clock_(clock), timeout_ms_(timeout_ms), log_(log) {}
  void kick() override;
  std::uint32_t timeout_ms() const override { return timeout_ms_; }
  std::uint32_t kicks() const { return kicks_; }
  std::uint32_t late_kicks() const { return late_; }

 private:
  const MonotonicClock& clock_;
  std::uint32_t timeout_ms_;
  LogSink* log_;
  std::uint64_t last_ns_ = 0;
  std::uint32_t kicks_ = 0;
  std::uint32_t late_ = 0;
};

}  // namespace bms::hal::lnx
