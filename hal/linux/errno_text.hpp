// errno as text for the Linux backend's error messages, thread-safe: std::strerror may
// return a buffer shared by all threads (clang-tidy concurrency-mt-unsafe), strerror_r
// writes into the caller's. glibc declares the GNU strerror_r (returns the text) when
// _GNU_SOURCE is set, as g++ and clang++ always do for C++, and the POSIX one (returns 0
// and fills the buffer) otherwise; the overloads below accept either.
#pragma once

#include <cstddef>
#include <cstring>

namespace bms::hal::lnx::detail {

inline const char* strerror_result(int rc, const char* buf) { return rc == 0 ? buf : "unknown error"; }
inline const char* strerror_result(const char* text, const char* /*buf*/) { return text; }

/// Text for `err`, valid while `buf` lives.
inline const char* errno_text(int err, char* buf, std::size_t len) {
  buf[0] = '\0';
  return strerror_result(::strerror_r(err, buf, len), buf);
}

}  // namespace bms::hal::lnx::detail
