// LogSink on the semihosting console (see board.hpp).
#include "bms/hal/cortex_m/board.hpp"

namespace bms::hal::cortex_m {

void SemihostLogSink::write(LogLevel level, const char* message) {
  if (level < min_level_) return;
  LogLine line;
  if (clock_ != nullptr) {
    const std::uint64_t t_ns = clock_->now_ns();
    const std::uint64_t micros = (t_ns % 1'000'000'000u) / 1000u;
    line.add('[').add(t_ns / 1'000'000'000u).add('.');
    for (std::uint64_t scale = 100000u; scale > 1u && micros < scale; scale /= 10u) line.add('0');
    line.add(micros);
    line.add("] ");
  }
  line.add(log_level_name(level)).add(": ").add(message);
  // LogLine cuts at kLogMessageMax - 1 characters; the newline goes out separately.
  bms_semihost_write(line.c_str(), line.size());
  bms_semihost_write("\n", 1u);
}

}  // namespace bms::hal::cortex_m
