// Log sink: a level and one line of text (no trailing newline). Messages longer than
// kLogMessageMax - 1 characters are cut by the sender. LogLine builds a message in a
// fixed buffer without printf (newlib's printf family may allocate for some conversions).
#pragma once

#include <cstddef>
#include <cstdint>

namespace bms::hal {

enum class LogLevel : std::uint8_t { debug = 0, info = 1, warning = 2, error = 3 };

constexpr const char* log_level_name(LogLevel l) {
  switch (l) {
    case LogLevel::debug: return "debug";
    case LogLevel::info: return "info";
    case LogLevel::warning: return "warning";
    case LogLevel::error: return "error";
  }
  return "unknown";
}

inline constexpr std::size_t kLogMessageMax = 160;  ///< buffer size, including the NUL

class LogSink {
 public:
  /// `message` is NUL-terminated; sinks must not keep the pointer.
  virtual void write(LogLevel level, const char* message) = 0;

 protected:
  LogSink() = default;
  LogSink(const LogSink&) = default;
  LogSink& operator=(const LogSink&) = default;
  ~LogSink() = default;
};

/// Fixed-buffer message builder: LogLine().add("tick ").add(k).add(" late").c_str().
/// Text that does not fit is cut; the result is always NUL-terminated.
class LogLine {
 public:
  // Only buf_[0..len_] is ever read: zeroing the whole buffer for every message would
  // cost time in the tick for nothing.
  LogLine() { buf_[0] = '\0'; }  // NOLINT(cppcoreguidelines-pro-type-member-init)

  LogLine& add(const char* s) {
    if (s == nullptr) return *this;
    while (*s != '\0' && len_ + 1 < kLogMessageMax) buf_[len_++] = *s++;
    buf_[len_] = '\0';
    return *this;
  }
  LogLine& add(char c) {
    const char s[2] = {c, '\0'};
    return add(s);
  }
  LogLine& add(std::uint64_t v) {
    char tmp[21];
    std::size_t n = 0;
    do {
      tmp[n++] = static_cast<char>('0' + static_cast<int>(v % 10u));
      v /= 10u;
    } while (v != 0u);
    char out[21];
    for (std::size_t i = 0; i < n; ++i) out[i] = tmp[n - 1 - i];
    out[n] = '\0';
    return add(static_cast<const char*>(out));
  }
  LogLine& add(std::int64_t v) {
    if (v < 0) {
      add('-');
      // -(v + 1) + 1 avoids overflow at INT64_MIN
      return add(static_cast<std::uint64_t>(-(v + 1)) + 1u);
    }
    return add(static_cast<std::uint64_t>(v));
  }
  LogLine& add(std::uint32_t v) { return add(static_cast<std::uint64_t>(v)); }
  LogLine& add(std::int32_t v) { return add(static_cast<std::int64_t>(v)); }
  /// Hexadecimal with "0x" and at least `digits` digits.
  LogLine& hex(std::uint32_t v, int digits = 1) {
    char tmp[9];
    int n = 0;
    do {
      const unsigned d = v & 0xFu;
      tmp[n++] = static_cast<char>(d < 10u ? '0' + static_cast<int>(d) : 'A' + static_cast<int>(d - 10u));
      v >>= 4u;
    } while ((v != 0u || n < digits) && n < 8);
    add("0x");
    while (n > 0) add(tmp[--n]);
    return *this;
  }

  const char* c_str() const { return buf_; }
  std::size_t size() const { return len_; }

 private:
  char buf_[kLogMessageMax];
  std::size_t len_ = 0;
};

}  // namespace bms::hal
