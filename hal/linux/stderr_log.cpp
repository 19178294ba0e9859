#include "bms/hal/linux/stderr_log.hpp"

#include <unistd.h>

#include <cstdio>

namespace bms::hal::lnx {

void StderrLogSink::write(LogLevel level, const char* message) {
  if (level < min_level_) return;
  char line[kLogMessageMax + 48];
  int n = 0;
  if (clock_ != nullptr) {
    const std::uint64_t t = clock_->now_ns();
    n = std::snprintf(line, sizeof line, "[%6llu.%06llu] %s: %s\n", static_cast<unsigned long long>(t / 1'000'000'000u),
                      static_cast<unsigned long long>((t % 1'000'000'000u) / 1000u), log_level_name(level),
                      message != nullptr ? message : "");
  } else {
    n = std::snprintf(line, sizeof line, "%s: %s\n", log_level_name(level), message != nullptr ? message : "");
  }
  if (n <= 0) return;
  std::size_t len = static_cast<std::size_t>(n) < sizeof line ? static_cast<std::size_t>(n) : sizeof line - 1;
  line[len - 1] = '\n';  // a cut message still ends its line (a whole one already does)
  const ssize_t w = ::write(fd_, line, len);
  (void)w;
}

void LoggingWatchdog::kick() {
  const std::uint64_t now = clock_.now_ns();
  if (timeout_ms_ != 0 && kicks_ > 0) {
    const std::uint64_t gap_ns = now - last_ns_;
    if (gap_ns > static_cast<std::uint64_t>(timeout_ms_) * 1'000'000u) {
      ++late_;
      if (log_ != nullptr) {
        LogLine l;
        l.add("watchdog: kick came ")
            .add(static_cast<std::uint64_t>(gap_ns / 1'000'000u))
            .add(" ms after the previous one (timeout ")
            .add(timeout_ms_)
            .add(" ms)");
        log_->write(LogLevel::warning, l.c_str());
      }
    }
  }
  last_ns_ = now;
  ++kicks_;
}

}  // namespace bms::hal::lnx
