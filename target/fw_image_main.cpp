// The firmware image as it would ship, minus the CAN driver: board support, the tick, the
// replay data as its input, output through the HAL's log sink only. No libc stdio and no
// semihosting syscalls layer (rdimon) are linked, so no heap can be: target/tools/
// noheap_check.py checks that the image defines no allocator at all, and footprint.py reports
// this image's flash and RAM as the firmware's footprint (with and without the replay data).
// Prints a progress line every 5000 ticks and the final estimate; exit status 0.
#include <bms/hal/cortex_m/board.hpp>
#include <cstdint>

#include "replay_data.hpp"
#include "replay_tick.hpp"

namespace {

using bms::hal::LogLevel;
using bms::hal::LogLine;
using bms::target::Scalar;

// Film resistance in units of 1e-12 ohm m2 (LogLine prints integers only).
std::int64_t pico(Scalar r_ohm_m2) { return static_cast<std::int64_t>(static_cast<double>(r_ohm_m2) * 1e12 + 0.5); }

}  // namespace

int main() {
  bms::hal::cortex_m::SysTickTimer timer;
  bms::hal::cortex_m::SemihostLogSink log(LogLevel::info, &timer);
  static bms::target::ReplayFirmware fw;
  std::uint32_t status_or = 0u;
  std::uint64_t worst = 0u;
  Scalar r_film = Scalar(0);
  for (std::size_t k = 0; k < kReplayTicks; ++k) {
    const Scalar voltage_v = static_cast<Scalar>(static_cast<double>(bms_replay_voltage_10uv[k]) * 1e-5);
    const Scalar current_a = static_cast<Scalar>(static_cast<double>(bms_replay_current_100ua[k]) * 1e-4);
    const std::uint64_t t0 = timer.now_ns();
    const bms::target::TickOutput out = bms::target::replay_tick(fw, voltage_v, current_a);
    const std::uint64_t cost = timer.now_ns() - t0;
    if (cost > worst) worst = cost;
    status_or |= out.status;
    r_film = out.r_film_est_ohm_m2;
    if (k % 5000u == 0u) {
      log.write(LogLevel::info, LogLine()
                                    .add("tick ")
                                    .add(static_cast<std::uint32_t>(k))
                                    .add(" mode ")
                                    .add(bms::fw::mode_name(out.mode))
                                    .add(" r_film_est ")
                                    .add(pico(r_film))
                                    .add("e-12 ohm m2")
                                    .c_str());
    }
  }
  log.write(LogLevel::info, LogLine()
                                .add("done: ")
                                .add(static_cast<std::uint32_t>(kReplayTicks))
                                .add(" ticks, r_film_est ")
                                .add(pico(r_film))
                                .add("e-12 ohm m2, status_or ")
                                .hex(status_or, 8)
                                .add(", worst tick ")
                                .add(worst)
                                .add(" instructions, stack used ")
                                .add(static_cast<std::uint32_t>(bms_board_stack_used_bytes()))
                                .add(" bytes")
                                .c_str());
  return 0;
}
