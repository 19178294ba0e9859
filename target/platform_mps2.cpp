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

void platform_report() {
  std::printf("# platform %s\n", BMS_TARGET_BOARD);
  std::printf("# stack_used_bytes %u of %u\n", static_cast<unsigned>(bms_board_stack_used_bytes()),
              static_cast<unsigned>(bms_board_stack_size_bytes()));
  std::printf("# libc_heap_used_bytes %u\n", static_cast<unsigned>(bms_board_heap_used_bytes()));
}

}  // namespace bms::target
