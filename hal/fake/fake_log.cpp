#include "bms/hal/fake/fake_log.hpp"

namespace bms::hal::fake {

void RecordingLogSink::write(LogLevel level, const char* message) {
  entries_.push_back({level, message != nullptr ? std::string(message) : std::string()});
}

std::size_t RecordingLogSink::count(LogLevel level) const {
  std::size_t n = 0;
  for (const Entry& e : entries_)
    if (e.level == level) ++n;
  return n;
}

bool RecordingLogSink::contains(const std::string& text, LogLevel min_level) const {
  for (const Entry& e : entries_)
    if (e.level >= min_level && e.message.find(text) != std::string::npos) return true;
  return false;
}

}  // namespace bms::hal::fake
