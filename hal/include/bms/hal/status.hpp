// Status codes shared by every HAL interface. No exceptions cross the HAL: every call
// that can fail returns one of these; a human-readable reason, where there is one, is
// available from the object's last_error().
#pragma once

#include <cstdint>

namespace bms::hal {

enum class Status : std::uint8_t {
  ok = 0,
  timeout,           ///< nothing arrived in time (also: non-blocking call found nothing)
  invalid_argument,  ///< bad length, id, filter count, alignment...
  out_of_range,      ///< offset/size outside the device
  not_open,          ///< the object was never opened or opening failed
  unsupported,       ///< the platform lacks the feature (e.g. a kernel without SocketCAN)
  not_found,         ///< a named device/interface does not exist
  io_error,          ///< the operation failed part-way (or a simulated power loss)
  overflow,          ///< a queue or buffer was full; data was lost
};

/// Short, stable name of a status ("ok", "timeout", ...), for logs and test output.
constexpr const char* status_name(Status s) {
  switch (s) {
    case Status::ok: return "ok";
    case Status::timeout: return "timeout";
    case Status::invalid_argument: return "invalid_argument";
    case Status::out_of_range: return "out_of_range";
    case Status::not_open: return "not_open";
    case Status::unsupported: return "unsupported";
    case Status::not_found: return "not_found";
    case Status::io_error: return "io_error";
    case Status::overflow: return "overflow";
  }
  return "unknown";
}

}  // namespace bms::hal
