#pragma once
// Operating mode of the cell; numbering shared with the DBC (VAL_), the contract's mode
// strings, the simulator's cycler and the firmware's mode detection.
#include <cstdint>

namespace bms::fw {

enum class Mode : std::uint8_t {
  rest = 0,
  cc_discharge = 1,
  cv_discharge = 2,
  cc_charge = 3,
  cv_charge = 4,
  unknown = 15,
};

constexpr const char* mode_name(Mode m) {
  switch (m) {
    case Mode::rest: return "rest";
    case Mode::cc_discharge: return "cc_discharge";
    case Mode::cv_discharge: return "cv_discharge";
    case Mode::cc_charge: return "cc_charge";
    case Mode::cv_charge: return "cv_charge";
    case Mode::unknown: return "unknown";
  }
  return "unknown";
}

}  // namespace bms::fw
