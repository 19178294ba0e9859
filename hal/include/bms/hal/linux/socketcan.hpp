// SocketCAN backend: a CAN_RAW socket bound to one interface (vcan0, can0...).
// Namespace bms::hal::lnx ("linux" is a predefined macro in GNU language modes).
#pragma once

#include <cstddef>
#include <cstdint>

#include "bms/hal/can_bus.hpp"

namespace bms::hal::lnx {

/// The error text when the running kernel has no CAN support (socket() -> EAFNOSUPPORT).
inline constexpr const char* kNoSocketCanMessage =
    "this kernel has no SocketCAN (EAFNOSUPPORT): use --bus uml or load vcan";

class SocketCanBus final : public CanBus {
 public:
  SocketCanBus() = default;
  ~SocketCanBus();
  SocketCanBus(const SocketCanBus&) = delete;
  SocketCanBus& operator=(const SocketCanBus&) = delete;

  /// Open a raw CAN socket on interface `ifname`. Errors (with last_error() set):
  /// unsupported - the kernel has no SocketCAN (kNoSocketCanMessage);
  /// not_found - no such interface; invalid_argument - name too long; io_error - other.
  Status open(const char* ifname);
  void close();
  bool is_open() const { return fd_ >= 0; }

  Status send(const CanFrame& frame) override;
  Status receive(CanFrame& frame, std::int32_t timeout_ms) override;
  Status set_filters(const CanFilter* filters, std::size_t count) override;
  const char* last_error() const override { return error_; }

  /// Receive the frames this socket sends itself (CAN_RAW_RECV_OWN_MSGS); off by default.
  Status set_receive_own(bool on);
  int native_handle() const { return fd_; }

 private:
  Status fail(Status s, const char* what, int err);
  int fd_ = -1;
  char error_[256] = "";
};

}  // namespace bms::hal::lnx
