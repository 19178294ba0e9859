// What the replay application needs from the platform it runs on; one implementation per
// platform, chosen at link time: platform_host.cpp (Linux) and platform_mps2.cpp (QEMU MPS2).
#pragma once

#include <cstdint>

namespace bms::hal {
class NonVolatileMemory;
class Watchdog;
}  // namespace bms::hal

namespace bms::target {

/// Starts the instruction counter (on the board: SysTick).
void platform_start();

/// Instructions executed since platform_start() on the board under
/// `qemu-system-arm -icount shift=0` (SysTick's virtual time, 40-instruction steps); 0 on
/// the host, whose output must not depend on timing.
std::uint64_t platform_instructions();

/// The platform's watchdog, armed by the call (board: the CMSDK APB watchdog with a deadline
/// of timeout_ms; host: a counter), and the kicks it has seen.
bms::hal::Watchdog& platform_watchdog(std::uint32_t timeout_ms);
std::uint32_t platform_watchdog_kicks();
/// "cmsdk" when the board's watchdog device is there, "counting" otherwise.
const char* platform_watchdog_kind();

/// The platform's non-volatile memory (board: RamNvm over the retained RAM; host: an array
/// with the same size and page size), erased by the first call.
bms::hal::NonVolatileMemory& platform_nvm();

/// Writes the platform's own summary lines ("# name value") to stdout.
void platform_report();

}  // namespace bms::target
