// QEMU MPS2 side of platform.hpp: SysTick counts instructions under -icount shift=0.
#include <bms/hal/cortex_m/board.hpp>
#include <cstdio>

#include "platform.hpp"

namespace bms::target {

namespace {
bms::hal::cortex_m::SysTickTimer& timer() {
  static bms::hal::cortex_m::SysTickTimer t;
  return t;
}
}  // namespace

void platform_start() { (void)timer(); }

std::uint64_t platform_instructions() { return timer().now_ns(); }

bms::hal::Watchdog& platform_watchdog(std::uint32_t timeout_ms) {
  static bms::hal::cortex_m::CmsdkWatchdog w;
  static bool armed = false;
  if (!armed) {
    w.start(timeout_ms);
    armed = true;
  }
  return w;
}

std::uint32_t platform_watchdog_kicks() {
  return static_cast<bms::hal::cortex_m::CmsdkWatchdog&>(platform_watchdog(0u)).kicks();
}

const char* platform_watchdog_kind() {
  return static_cast<bms::hal::cortex_m::CmsdkWatchdog&>(platform_watchdog(0u)).present() ? "cmsdk" : "counting";
}

bms::hal::NonVolatileMemory& platform_nvm() {
  static bms::hal::cortex_m::RamNvm nvm(bms::hal::cortex_m::retained_ram(), bms::hal::cortex_m::kRetainedRamBytes, 256u);
  static const bool erased = nvm.erase(0u, nvm.size_bytes()) == bms::hal::Status::ok;
  (void)erased;
  return nvm;
}

void platform_report() {
  std::printf("# platform %s\n", BMS_TARGET_BOARD);
  std::printf("# stack_used_bytes %u of %u\n", static_cast<unsigned>(bms_board_stack_used_bytes()),
              static_cast<unsigned>(bms_board_stack_size_bytes()));
  std::printf("# libc_heap_used_bytes %u\n", static_cast<unsigned>(bms_board_heap_used_bytes()));
}

}  // namespace bms::target
