#include "bms/hal/linux/timerfd_tick.hpp"

#include <poll.h>
#include <sys/timerfd.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <ctime>

#include "errno_text.hpp"

namespace bms::hal::lnx {

TimerfdTickSource::~TimerfdTickSource() { close(); }

void TimerfdTickSource::close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

Status TimerfdTickSource::fail(Status s, const char* what, int err) {
  char text[96];
  // snprintf's result is not needed: a message longer than the buffer is cut, on purpose.
  (void)std::snprintf(error_, sizeof error_, "%s%s%s", what, err != 0 ? ": " : "",
                      err != 0 ? detail::errno_text(err, text, sizeof text) : "");
  return s;
}

Status TimerfdTickSource::open(std::uint64_t period_ns) {
  close();
  if (period_ns == 0) return fail(Status::invalid_argument, "tick period must be positive", 0);
  const int fd = ::timerfd_create(CLOCK_MONOTONIC, TFD_CLOEXEC | TFD_NONBLOCK);
  if (fd < 0) return fail(Status::io_error, "timerfd_create(CLOCK_MONOTONIC) failed", errno);
  itimerspec spec{};
  spec.it_interval.tv_sec = static_cast<time_t>(period_ns / 1'000'000'000u);
  spec.it_interval.tv_nsec = static_cast<long>(period_ns % 1'000'000'000u);
  spec.it_value = spec.it_interval;
  if (::timerfd_settime(fd, 0, &spec, nullptr) < 0) {
    const int err = errno;
    ::close(fd);
    return fail(Status::io_error, "timerfd_settime failed", err);
  }
  fd_ = fd;
  period_ns_ = period_ns;
  expirations_ = 0;
  missed_ = 0;
  return Status::ok;
}

Status TimerfdTickSource::wait_next_tick(std::uint32_t& tick, std::int32_t timeout_ms) {
  if (fd_ < 0) return fail(Status::not_open, "tick source is not open", 0);
  for (;;) {
    pollfd p{fd_, POLLIN, 0};
    const int r = ::poll(&p, 1, timeout_ms < 0 ? -1 : timeout_ms);
    if (r < 0) {
      if (errno == EINTR) continue;
      return fail(Status::io_error, "poll on timerfd failed", errno);
    }
    if (r == 0) return Status::timeout;
    std::uint64_t n = 0;
    const ssize_t got = ::read(fd_, &n, sizeof n);
    if (got < 0 && (errno == EINTR || errno == EAGAIN)) continue;
    if (got != static_cast<ssize_t>(sizeof n)) return fail(Status::io_error, "read from timerfd failed", errno);
    if (n == 0) continue;
    expirations_ += n;
    missed_ += static_cast<std::uint32_t>(n - 1u);
    tick = static_cast<std::uint32_t>(expirations_ - 1u);
    return Status::ok;
  }
}

}  // namespace bms::hal::lnx
