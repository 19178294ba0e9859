// Host (Linux) side of platform.hpp: no instruction counter; a counting watchdog and an
// array as non-volatile memory.
#include "platform.hpp"

#include "bms/hal/ram_nvm.hpp"
#include "bms/hal/watchdog.hpp"

#include <cstdio>
#include <cstdint>

namespace bms::target {

namespace {

class CountingWatchdog final : public bms::hal::Watchdog {
 public:
  void kick() override { ++kicks; }
  std::uint32_t kicks = 0;
};

// The board's RamNvm over 4 KiB of RAM, as on the board.
std::uint8_t g_retained[4096];

CountingWatchdog g_watchdog;

}  // namespace

void platform_start() {}
std::uint64_t platform_instructions() { return 0u; }
void platform_report() { std::printf("# platform host\n"); }

bms::hal::Watchdog& platform_watchdog(std::uint32_t) { return g_watchdog; }
std::uint32_t platform_watchdog_kicks() { return g_watchdog.kicks; }
const char* platform_watchdog_kind() { return "counting"; }

bms::hal::NonVolatileMemory& platform_nvm() {
  static bms::hal::RamNvm nvm(g_retained, sizeof g_retained, 256u);
  static const bool erased = nvm.erase(0, nvm.size_bytes()) == bms::hal::Status::ok;
  (void)erased;
  return nvm;
}

}  // namespace bms::target
