// Target test application: the firmware application (bms::app::BmsApplication, firmware/app)
// on the board, the same class bms-firmware runs on Linux. The replay data's measurements go
// in as HOST_Measurement frames over a memory CAN bus (bms/hal/memory_can.hpp; QEMU's MPS2
// has no CAN controller), the application runs its tick in lock-step with them, and the
// BMS_Estimate1 / BMS_Status frames it answers with are decoded on the host side of the bus.
// Beside it the direct replay (replay_tick, as replay_main) runs the same samples. Checks:
//   - the decoded film estimate equals the direct replay's, to the bus's resolution, on
//     every tick, and the mode agrees;
//   - the watchdog (platform_watchdog: the board's CMSDK watchdog) was kicked every tick;
//   - no fault bit in any BMS_Status (none is expected on this clean cycle);
//   - the state is committed to the NVM (RamNvm on the board) at the end of the first CC
//     charge, and a second application (a power cycle) restores it and carries on.
// Prints "# name value" summary lines; exit status 0 when every check holds.
#include <bms/app/bms_application.hpp>
#include <bms/hal/lockstep.hpp>
#include <bms/hal/memory_can.hpp>
#include <cmath>
#include <cstdint>
#include <cstdio>

#include "platform.hpp"
#include "replay_data.hpp"
#include "replay_tick.hpp"

namespace {

namespace can = bms::fw::can;
namespace hal = bms::hal;
using bms::target::Core;
using bms::target::Model;
using bms::target::Scalar;
using App = bms::app::BmsApplication<Core>;
using Bus = hal::MemoryCanBus<16>;

constexpr std::uint32_t kWatchdogTimeoutMs = 1000u;
constexpr double kRFilmStepOhmM2 = 1e-10;  // BMS_Estimate1.RFilm's resolution

// The instruction counter as the application's clock (1 ns per instruction under QEMU's
// -icount shift=0; 0 on the host, where no tick can overrun).
class PlatformClock final : public hal::MonotonicClock {
 public:
  std::uint64_t now_ns() const override { return bms::target::platform_instructions(); }
};

class NullLog final : public hal::LogSink {
 public:
  void write(hal::LogLevel, const char*) override {}
};

bool classify(const hal::CanFrame& f, std::uint32_t& t, void* c) { return static_cast<can::LockstepTicks*>(c)->classify(f, t); }

PlatformClock g_clock;
NullLog g_log;
Bus g_host_side, g_bms_side;

// One power-on of the firmware: its model, core, lock-step tick rule and application.
struct Board {
  Board()
      : model(bms::target::initial_firmware_model()),
        core(bms::target::firmware_config(), model),
        bus(g_bms_side, classify, &rule),
        app(core, bus, bus, g_log, bms::target::platform_nvm(), options()) {}
  App::Options options() {
    App::Options o;
    o.lockstep = true;
    o.lockstep_ticks = &rule;
    o.tick_timeout_ms = 0;
    o.persist_every_ticks = 0;  // commits at the end of a CC charge only
    o.watchdog = &bms::target::platform_watchdog(kWatchdogTimeoutMs);
    o.clock = &g_clock;
    return o;
  }
  Model model;
  Core core;
  can::LockstepTicks rule;
  hal::LockstepBus<8> bus;
  App app;
};

struct Answer {
  bool have_estimate = false, have_status = false;
  can::Estimate1 estimate;
  can::BmsStatus status;
};

Answer read_answer() {
  Answer a;
  hal::CanFrame f{};
  while (g_host_side.receive(f, hal::kCanNoWait) == hal::Status::ok) {
    if (f.id == can::id::kEstimate1) a.have_estimate = can::decode(f, a.estimate);
    if (f.id == can::id::kStatus) a.have_status = can::decode(f, a.status);
  }
  return a;
}

struct Tally {
  std::uint32_t ticks = 0, answered = 0, film_mismatches = 0, mode_mismatches = 0;
  double film_max_diff_steps = 0.0;
  std::uint8_t fault_or = 0;
  std::uint32_t power_cycle_tick = 0xFFFFFFFFu;
  bool restored = false;
};

void compare(const Answer& a, const bms::target::TickOutput& direct, std::uint32_t k, Tally& t) {
  if (!a.have_estimate || !a.have_status) return;
  ++t.answered;
  t.fault_or = static_cast<std::uint8_t>(t.fault_or | a.status.fault_bits);
  const double diff_steps = std::fabs(a.estimate.r_film_ohm_m2 - static_cast<double>(direct.r_film_est_ohm_m2)) /
                            kRFilmStepOhmM2;
  if (diff_steps > t.film_max_diff_steps) t.film_max_diff_steps = diff_steps;
  // The encoder rounds to the nearest step: half a step, plus the decoder's round-off.
  if (!(diff_steps <= 0.5 + 1e-6)) {
    if (t.film_mismatches++ < 5u)
      std::printf("# mismatch tick %u film bus %.12g direct %.12g\n", static_cast<unsigned>(k),
                  a.estimate.r_film_ohm_m2, static_cast<double>(direct.r_film_est_ohm_m2));
  }
  if (a.estimate.mode != direct.mode) ++t.mode_mismatches;
}

}  // namespace

int main() {
  bms::target::platform_start();
  Bus::connect(g_host_side, g_bms_side);
  static bms::target::ReplayFirmware direct;
  static Board first;
  static Board second;
  Board* board = &first;
  can::Transmitter host_tx;
  Tally t;
  for (std::size_t k = 0; k < kReplayTicks; ++k) {
    can::Measurement m;
    m.seq = static_cast<std::uint16_t>(k & can::kSeqMask);
    m.voltage_v = static_cast<double>(bms_replay_voltage_10uv[k]) * 1e-5;
    m.current_a = static_cast<double>(bms_replay_current_100ua[k]) * 1e-4;
    hal::CanFrame f{};
    host_tx.encode(m, f);
    if (g_host_side.send(f) != hal::Status::ok) break;
    const bms::target::TickOutput d = bms::target::replay_tick(direct, static_cast<Scalar>(m.voltage_v),
                                                               static_cast<Scalar>(m.current_a));
    if (board->app.step() != hal::Status::ok) break;
    ++t.ticks;
    compare(read_answer(), d, static_cast<std::uint32_t>(k), t);
    // A power cycle right after the first commit: the second board restores that state.
    if (board == &first && first.app.nvm_counters().commits > 0u) {
      t.power_cycle_tick = static_cast<std::uint32_t>(k);
      t.restored = second.app.restore_from_nvm();
      board = &second;
    }
  }
  const std::uint32_t kicks = bms::target::platform_watchdog_kicks();
  std::printf("# app_ticks %u of %u\n", static_cast<unsigned>(t.ticks), static_cast<unsigned>(kReplayTicks));
  std::printf("# answered_ticks %u\n", static_cast<unsigned>(t.answered));
  std::printf("# film_mismatches %u (max %.3f bus steps of %.0e ohm m2)\n", static_cast<unsigned>(t.film_mismatches),
              t.film_max_diff_steps, kRFilmStepOhmM2);
  std::printf("# mode_mismatches %u\n", static_cast<unsigned>(t.mode_mismatches));
  std::printf("# watchdog %s kicks %u\n", bms::target::platform_watchdog_kind(), static_cast<unsigned>(kicks));
  std::printf("# fault_bits_or 0x%02x\n", static_cast<unsigned>(t.fault_or));
  std::printf("# nvm_commits %u power_cycle_tick %u restored %u\n",
              static_cast<unsigned>(first.app.nvm_counters().commits + second.app.nvm_counters().commits),
              static_cast<unsigned>(t.power_cycle_tick), t.restored ? 1u : 0u);
  std::printf("# tick_overruns %u worst_tick_ns %lu\n",
              static_cast<unsigned>(first.app.supervisor().overruns() + second.app.supervisor().overruns()),
              static_cast<unsigned long>(first.app.supervisor().worst_tick_ns() > second.app.supervisor().worst_tick_ns()
                                             ? first.app.supervisor().worst_tick_ns()
                                             : second.app.supervisor().worst_tick_ns()));
  bms::target::platform_report();
  const bool ok = t.ticks == kReplayTicks && t.answered == t.ticks && t.film_mismatches == 0u &&
                  t.mode_mismatches == 0u && kicks == t.ticks && t.fault_or == 0u && t.restored;
  std::printf("# app_check %s\n", ok ? "pass" : "FAIL");
  return ok ? 0 : 1;
}
