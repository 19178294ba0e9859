// The board's retained RAM, the storage of its RamNvm (bms/hal/ram_nvm.hpp; see board.hpp).
#include "bms/hal/cortex_m/board.hpp"

namespace {
// In .noinit: Reset_Handler does not zero it, so a warm reset keeps the contents.
__attribute__((section(".noinit"))) std::uint8_t g_retained[bms::hal::cortex_m::kRetainedRamBytes];
}  // namespace

namespace bms::hal::cortex_m {

std::uint8_t* retained_ram() { return g_retained; }

}  // namespace bms::hal::cortex_m
