// What the replay application needs from the platform it runs on; one implementation per
// platform, chosen at link time: platform_host.cpp (Linux) and platform_mps2.cpp (QEMU MPS2).
#pragma once

#include <cstdint>

namespace bms::target {

/// Starts the instruction counter (on the board: SysTick).
void platform_start();

/// Instructions executed since platform_start() on the board under
/// `qemu-system-arm -icount shift=0` (SysTick's virtual time, 40-instruction steps); 0 on
/// the host, whose output must not depend on timing.
std::uint64_t platform_instructions();

/// Writes the platform's own summary lines ("# name value") to stdout.
void platform_report();

}  // namespace bms::target
