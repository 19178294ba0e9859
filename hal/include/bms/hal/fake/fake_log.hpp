// Recording log sink and counting watchdog for unit tests.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "bms/hal/log_sink.hpp"
#include "bms/hal/watchdog.hpp"

namespace bms::hal::fake {

class RecordingLogSink final : public LogSink {
 public:
  struct Entry {
    LogLevel level;
    std::string message;
  };

  void write(LogLevel level, const char* message) override;

  const std::vector<Entry>& entries() const { return entries_; }
  std::size_t count(LogLevel level) const;
  /// True when some entry (at `min_level` or above) contains `text`.
  bool contains(const std::string& text, LogLevel min_level = LogLevel::debug) const;
  void clear() { entries_.clear(); }

 private:
  std::vector<Entry> entries_;
};

class CountingWatchdog final : public Watchdog {
 public:
  explicit CountingWatchdog(std::uint32_t timeout_ms = 0) : timeout_ms_(timeout_ms) {}
  void kick() override { ++kicks_; }
  std::uint32_t timeout_ms() const override { return timeout_ms_; }
  std::uint32_t kicks() const { return kicks_; }

 private:
  std::uint32_t timeout_ms_;
  std::uint32_t kicks_ = 0;
};

}  // namespace bms::hal::fake
