#include "bms/hal/linux/socketcan.hpp"

#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <poll.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

#include "errno_text.hpp"

namespace bms::hal::lnx {

static_assert(kCanIdExtended == CAN_EFF_FLAG, "CanFrame's extended flag mirrors Linux CAN_EFF_FLAG");

SocketCanBus::~SocketCanBus() { close(); }

void SocketCanBus::close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

Status SocketCanBus::fail(Status s, const char* what, int err) {
  // snprintf's result is not needed here and below: a long message is cut, on purpose.
  if (err != 0) {
    char text[96];
    (void)std::snprintf(error_, sizeof error_, "%s: %s", what, detail::errno_text(err, text, sizeof text));
  } else {
    (void)std::snprintf(error_, sizeof error_, "%s", what);
  }
  return s;
}

Status SocketCanBus::open(const char* ifname) {
  close();
  error_[0] = '\0';
  if (ifname == nullptr || ifname[0] == '\0') return fail(Status::invalid_argument, "CAN interface name is empty", 0);
  ifreq ifr{};
  if (std::strlen(ifname) >= sizeof ifr.ifr_name) {
    char what[96];
    (void)std::snprintf(what, sizeof what, "CAN interface name '%.40s...' is too long", ifname);
    return fail(Status::invalid_argument, what, 0);
  }
  const int fd = ::socket(PF_CAN, SOCK_RAW | SOCK_CLOEXEC, CAN_RAW);
  if (fd < 0) {
    const int err = errno;
    if (err == EAFNOSUPPORT) return fail(Status::unsupported, kNoSocketCanMessage, 0);
    return fail(Status::io_error, "socket(PF_CAN, SOCK_RAW, CAN_RAW) failed", err);
  }
  std::memcpy(ifr.ifr_name, ifname, std::strlen(ifname) + 1);
  if (::ioctl(fd, SIOCGIFINDEX, &ifr) < 0) {
    const int err = errno;
    ::close(fd);
    char what[200];
    if (err == ENODEV) {
      (void)std::snprintf(what, sizeof what,
                    "no CAN interface '%s' (ENODEV): create it with 'ip link add dev %s type vcan && ip link set "
                    "up %s'",
                    ifname, ifname, ifname);
      return fail(Status::not_found, what, 0);
    }
    (void)std::snprintf(what, sizeof what, "ioctl(SIOCGIFINDEX, '%s') failed", ifname);
    return fail(Status::io_error, what, err);
  }
  sockaddr_can addr{};
  addr.can_family = AF_CAN;
  addr.can_ifindex = ifr.ifr_ifindex;
  // bind() takes the generic sockaddr*: the POSIX socket API's own cast.
  if (::bind(fd, reinterpret_cast<const sockaddr*>(&addr), sizeof addr) < 0) {  // NOLINT(cppcoreguidelines-pro-type-reinterpret-cast)
    const int err = errno;
    ::close(fd);
    char what[96];
    (void)std::snprintf(what, sizeof what, "bind to CAN interface '%s' failed", ifname);
    return fail(Status::io_error, what, err);
  }
  fd_ = fd;
  return Status::ok;
}

Status SocketCanBus::set_receive_own(bool on) {
  if (fd_ < 0) return fail(Status::not_open, "CAN bus is not open", 0);
  const int v = on ? 1 : 0;
  if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_RECV_OWN_MSGS, &v, sizeof v) < 0)
    return fail(Status::io_error, "setsockopt(CAN_RAW_RECV_OWN_MSGS) failed", errno);
  return Status::ok;
}

Status SocketCanBus::send(const CanFrame& frame) {
  if (fd_ < 0) return fail(Status::not_open, "CAN bus is not open", 0);
  if (!can_frame_valid(frame)) return fail(Status::invalid_argument, "invalid CAN frame (id or length)", 0);
  can_frame f{};
  f.can_id = frame.id;  // same encoding, CAN_EFF_FLAG included
  f.can_dlc = frame.len;
  std::memcpy(f.data, frame.data, frame.len);
  for (;;) {
    const ssize_t n = ::write(fd_, &f, sizeof f);
    if (n == static_cast<ssize_t>(sizeof f)) return Status::ok;
    if (n < 0 && errno == EINTR) continue;
    const int err = n < 0 ? errno : EIO;
    if (err == ENOBUFS || err == EAGAIN) return fail(Status::overflow, "CAN transmit queue full", err);
    return fail(Status::io_error, "CAN write failed", err);
  }
}

Status SocketCanBus::receive(CanFrame& frame, std::int32_t timeout_ms) {
  if (fd_ < 0) return fail(Status::not_open, "CAN bus is not open", 0);
  int wait_ms = timeout_ms < 0 ? -1 : timeout_ms;
  for (;;) {
    pollfd p{fd_, POLLIN, 0};
    const int r = ::poll(&p, 1, wait_ms);
    if (r < 0) {
      if (errno == EINTR) continue;
      return fail(Status::io_error, "poll on CAN socket failed", errno);
    }
    if (r == 0) return Status::timeout;
    can_frame f{};
    const ssize_t n = ::recv(fd_, &f, sizeof f, MSG_DONTWAIT);
    if (n < 0) {
      if (errno == EINTR || errno == EAGAIN) continue;
      return fail(Status::io_error, "CAN read failed", errno);
    }
    if (n != static_cast<ssize_t>(sizeof f)) continue;                   // CAN FD or short: not ours
    if ((f.can_id & (CAN_ERR_FLAG | CAN_RTR_FLAG)) != 0u) {            // error/remote frames: skip
      wait_ms = 0;
      continue;
    }
    frame.id = f.can_id & (CAN_EFF_FLAG | ((f.can_id & CAN_EFF_FLAG) != 0u ? CAN_EFF_MASK : CAN_SFF_MASK));
    frame.len = f.can_dlc > kCanMaxLen ? kCanMaxLen : f.can_dlc;
    std::memset(frame.data, 0, sizeof frame.data);
    std::memcpy(frame.data, f.data, frame.len);
    return Status::ok;
  }
}

Status SocketCanBus::set_filters(const CanFilter* filters, std::size_t count) {
  if (fd_ < 0) return fail(Status::not_open, "CAN bus is not open", 0);
  if (count > kCanMaxFilters || (count > 0 && filters == nullptr))
    return fail(Status::invalid_argument, "too many CAN filters", 0);
  can_filter kf[kCanMaxFilters];
  for (std::size_t i = 0; i < count; ++i) {
    kf[i].can_id = filters[i].id;
    kf[i].can_mask = filters[i].mask;
  }
  const auto len = static_cast<socklen_t>(count * sizeof(can_filter));
  if (::setsockopt(fd_, SOL_CAN_RAW, CAN_RAW_FILTER, count > 0 ? kf : nullptr, len) < 0)
    return fail(Status::io_error, "setsockopt(CAN_RAW_FILTER) failed", errno);
  return Status::ok;
}

}  // namespace bms::hal::lnx
