// SocketCAN backend: a CAN_RAW socket bound to one interface (vcan0, can0...).
// Namespace bms::hal::lnx ("linux" is a predefined macro in GNU language modes).
#pragma once

#include <cstddef>
#include <cstdint>

#include <linux/can.h>

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
  /// Queued, sent with the others in one sendmmsg at flush() (or when kTxBatch are queued).
  Status send_deferred(const CanFrame& frame) override;
  Status flush() override;
  Status receive(CanFrame& frame, std::int32_t timeout_ms) override;
  Status set_filters(const CanFilter* filters, std::size_t count) override;
  const char* last_error() const override { return error_; }

  /// Receive the frames this socket sends itself (CAN_RAW_RECV_OWN_MSGS); off by default.
  Status set_receive_own(bool on);
  int native_handle() const { return fd_; }

 private:
  static constexpr std::size_t kTxBatch = 16;
  static constexpr std::size_t kRxBatch = 16;
  Status fail(Status s, const char* what, int err);
  Status read_batch(std::int32_t wait_ms);
  Status set_receive_timeout(std::int32_t wait_ms);
  int fd_ = -1;
  can_frame tx_[kTxBatch]{};
  std::size_t tx_count_ = 0;
  can_frame rx_[kRxBatch]{};  // read by one recvmmsg, handed out from rx_head_
  std::size_t rx_head_ = 0;
  std::size_t rx_count_ = 0;
  std::int32_t rcv_timeout_ms_ = -1;  // SO_RCVTIMEO as set; -1: none (wait forever), the default
  char error_[256] = "";
};

}  // namespace bms::hal::lnx
