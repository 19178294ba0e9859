// The MPS2's CMSDK APB watchdog (see board.hpp). Register map: ARM CMSDK technical reference
// (DDI 0479), section "APB watchdog".
#include <cstdint>

#include "bms/hal/cortex_m/board.hpp"

namespace bms::hal::cortex_m {

namespace {
constexpr std::uintptr_t kLoad = 0x000u;
constexpr std::uintptr_t kValue = 0x004u;
constexpr std::uintptr_t kControl = 0x008u;
constexpr std::uintptr_t kIntClear = 0x00Cu;
constexpr std::uintptr_t kLock = 0xC00u;
constexpr std::uintptr_t kPeriphId0 = 0xFE0u;
constexpr std::uintptr_t kPeriphId1 = 0xFE4u;
constexpr std::uint32_t kUnlockKey = 0x1ACCE551u;
constexpr std::uint32_t kControlIntEnable = 1u << 0;
constexpr std::uint32_t kControlResetEnable = 1u << 1;

volatile std::uint32_t& reg(std::uintptr_t offset) {
  return *reinterpret_cast<volatile std::uint32_t*>(CmsdkWatchdog::kBase + offset);
}
}  // namespace

void CmsdkWatchdog::start(std::uint32_t timeout_ms) {
  timeout_ms_ = timeout_ms;
  // The CMSDK watchdog's part number 0x824 is in its peripheral ID 0 and 1 (0x24, 0xB8).
  present_ = (reg(kPeriphId0) & 0xFFu) == 0x24u && (reg(kPeriphId1) & 0x0Fu) == 0x08u;
  if (!present_) return;
  const std::uint64_t counts = static_cast<std::uint64_t>(kSysClockHz) / 1000u * timeout_ms;
  reg(kLock) = kUnlockKey;
  reg(kLoad) = counts > 0xFFFFFFFFu ? 0xFFFFFFFFu : static_cast<std::uint32_t>(counts);
  reg(kControl) = kControlIntEnable | kControlResetEnable;
  reg(kLock) = 0u;
}

void CmsdkWatchdog::kick() {
  ++kicks_;
  if (!present_) return;
  reg(kLock) = kUnlockKey;
  reg(kIntClear) = 1u;  // any write clears the interrupt and reloads the counter
  reg(kLock) = 0u;
}

std::uint32_t CmsdkWatchdog::counter() const { return present_ ? reg(kValue) : 0u; }

}  // namespace bms::hal::cortex_m
