#include "bms/hal/linux/socketcan.hpp"

#include <linux/can.h>
#include <linux/can/raw.h>
#include <net/if.h>
#include <sys/ioctl.h>
#include <sys/socket.h>
#include <sys/time.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

#include "errno_text.hpp"

namespace bms::hal::lnx {

static_assert(kCanIdExtended == CAN_EFF_FLAG, "CanFrame's extended flag mirrors Linux CAN_EFF_FLAG");

SocketCanBus::~SocketCanBus() { close(); }

void SocketCanBus::close() {
  if (fd_ >= 0) {
    (void)flush();  // frames queued by send_deferred still go out
    ::close(fd_);
  }
  tx_count_ = rx_head_ = rx_count_ = 0;
  rcv_timeout_ms_ = -1;
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

namespace {

can_frame to_linux(const CanFrame& frame) {
  can_frame f{};
  f.can_id = frame.id;  // same encoding, CAN_EFF_FLAG included
  f.can_dlc = frame.len;
  std::memcpy(f.data, frame.data, frame.len);
  return f;
}

// False for what the BMS never reads: error and remote frames.
bool from_linux(const can_frame& f, CanFrame& frame) {
  if ((f.can_id & (CAN_ERR_FLAG | CAN_RTR_FLAG)) != 0u) return false;
  frame.id = f.can_id & (CAN_EFF_FLAG | ((f.can_id & CAN_EFF_FLAG) != 0u ? CAN_EFF_MASK : CAN_SFF_MASK));
  frame.len = f.can_dlc > kCanMaxLen ? kCanMaxLen : f.can_dlc;
  std::memset(frame.data, 0, sizeof frame.data);
  std::memcpy(frame.data, f.data, frame.len);
  return true;
}

Status send_error(int err) { return err == ENOBUFS || err == EAGAIN ? Status::overflow : Status::io_error; }

}  // namespace

Status SocketCanBus::send_deferred(const CanFrame& frame) {
  if (fd_ < 0) return fail(Status::not_open, "CAN bus is not open", 0);
  if (!can_frame_valid(frame)) return fail(Status::invalid_argument, "invalid CAN frame (id or length)", 0);
  if (tx_count_ == kTxBatch) {
    const Status s = flush();
    if (s != Status::ok) return s;
  }
  tx_[tx_count_++] = to_linux(frame);
  return Status::ok;
}

// One sendmmsg for the whole batch: the system call, not the frame, is what costs under UML.
Status SocketCanBus::flush() {
  std::size_t sent = 0;
  while (sent < tx_count_) {
    mmsghdr msgs[kTxBatch]{};
    iovec iov[kTxBatch]{};
    const std::size_t n = tx_count_ - sent;
    for (std::size_t i = 0; i < n; ++i) {
      iov[i] = iovec{&tx_[sent + i], sizeof(can_frame)};
      msgs[i].msg_hdr.msg_iov = &iov[i];
      msgs[i].msg_hdr.msg_iovlen = 1;
    }
    const int r = ::sendmmsg(fd_, msgs, static_cast<unsigned>(n), 0);
    if (r < 0 && errno == EINTR) continue;
    if (r <= 0) {
      const int err = r < 0 ? errno : EIO;
      tx_count_ = 0;  // dropped, as a failed send() drops its frame
      return fail(send_error(err), err == ENOBUFS || err == EAGAIN ? "CAN transmit queue full" : "CAN write failed",
                  err);
    }
    sent += static_cast<std::size_t>(r);
  }
  tx_count_ = 0;
  return Status::ok;
}

Status SocketCanBus::send(const CanFrame& frame) {
  if (fd_ < 0) return fail(Status::not_open, "CAN bus is not open", 0);
  if (!can_frame_valid(frame)) return fail(Status::invalid_argument, "invalid CAN frame (id or length)", 0);
  if (tx_count_ > 0) {  // keep the order of frames queued by send_deferred
    const Status s = flush();
    if (s != Status::ok) return s;
  }
  const can_frame f = to_linux(frame);
  for (;;) {
    const ssize_t n = ::write(fd_, &f, sizeof f);
    if (n == static_cast<ssize_t>(sizeof f)) return Status::ok;
    if (n < 0 && errno == EINTR) continue;
    const int err = n < 0 ? errno : EIO;
    if (err == ENOBUFS || err == EAGAIN) return fail(Status::overflow, "CAN transmit queue full", err);
    return fail(Status::io_error, "CAN write failed", err);
  }
}

// Frames already read by the last recvmmsg are handed out without a system call; an empty
// buffer costs one recvmmsg that waits for the first frame and takes all that are queued.
Status SocketCanBus::receive(CanFrame& frame, std::int32_t timeout_ms) {
  if (fd_ < 0) return fail(Status::not_open, "CAN bus is not open", 0);
  std::int32_t wait_ms = timeout_ms < 0 ? -1 : timeout_ms;
  for (;;) {
    while (rx_head_ < rx_count_)
      if (from_linux(rx_[rx_head_++], frame)) return Status::ok;
    const Status s = read_batch(wait_ms);
    if (s != Status::ok) return s;
    wait_ms = 0;  // a batch of error/remote frames only: do not wait again for the caller
  }
}

// The wait rides on SO_RCVTIMEO (set only when it changes) instead of a poll() before each
// read: under User-Mode Linux every system call is a round trip through ptrace.
Status SocketCanBus::set_receive_timeout(std::int32_t wait_ms) {
  if (wait_ms == rcv_timeout_ms_) return Status::ok;
  timeval tv{};  // 0: wait forever
  if (wait_ms > 0) {
    tv.tv_sec = wait_ms / 1000;
    tv.tv_usec = static_cast<suseconds_t>((wait_ms % 1000) * 1000);
  }
  if (::setsockopt(fd_, SOL_SOCKET, SO_RCVTIMEO, &tv, sizeof tv) < 0)
    return fail(Status::io_error, "setsockopt(SO_RCVTIMEO) failed", errno);
  rcv_timeout_ms_ = wait_ms;
  return Status::ok;
}

Status SocketCanBus::read_batch(std::int32_t wait_ms) {
  if (wait_ms != 0) {
    const Status s = set_receive_timeout(wait_ms);
    if (s != Status::ok) return s;
  }
  mmsghdr msgs[kRxBatch]{};
  iovec iov[kRxBatch]{};
  for (std::size_t i = 0; i < kRxBatch; ++i) {
    iov[i] = iovec{&rx_[i], sizeof(can_frame)};
    msgs[i].msg_hdr.msg_iov = &iov[i];
    msgs[i].msg_hdr.msg_iovlen = 1;
  }
  rx_head_ = rx_count_ = 0;
  const int flags = wait_ms == 0 ? MSG_DONTWAIT : MSG_WAITFORONE;
  int n = -1;
  do {
    n = ::recvmmsg(fd_, msgs, kRxBatch, flags, nullptr);
  } while (n < 0 && errno == EINTR);
  if (n < 0) {
    if (errno == EAGAIN || errno == EWOULDBLOCK) return Status::timeout;
    return fail(Status::io_error, "CAN read failed", errno);
  }
  // CAN FD or short reads are not ours: keep only whole classic frames, in order.
  for (int i = 0; i < n; ++i)
    if (msgs[i].msg_len == sizeof(can_frame)) rx_[rx_count_++] = rx_[i];
  return Status::ok;
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
