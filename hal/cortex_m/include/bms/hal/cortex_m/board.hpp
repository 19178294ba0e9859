// Board support for QEMU's MPS2 boards (mps2-an500 Cortex-M7, mps2-an386 Cortex-M4F):
// implementations of the HAL interfaces that make sense there.
//
//   SysTickTimer     TickSource (one SysTick interrupt per 0.2 s tick) and MonotonicClock
//                    (40 ns resolution); under `qemu-system-arm -icount shift=0` its readings
//                    count instructions (one instruction = 1 ns of virtual time)
//   SemihostLogSink  LogSink on the semihosting console (QEMU -semihosting)
//   RamNvm           NonVolatileMemory over RAM (kept over a warm reset, lost at power-off)
//   CmsdkWatchdog    Watchdog: the MPS2's CMSDK APB watchdog at 0x40008000 (QEMU models it)
//
// The board has no CAN controller that QEMU emulates: the application runs over
// bms::hal::MemoryCanBus (bms/hal/memory_can.hpp) there. Everything is single-threaded (no RTOS); the only
// interrupt is SysTick. No heap, no exceptions, no RTTI.
#pragma once

#include <cstddef>
#include <cstdint>

#include "bms/hal/cortex_m/board.h"
#include "bms/hal/log_sink.hpp"
#include "bms/hal/monotonic_clock.hpp"
#include "bms/hal/nvm.hpp"
#include "bms/hal/ram_nvm.hpp"
#include "bms/hal/status.hpp"
#include "bms/hal/tick_source.hpp"
#include "bms/hal/watchdog.hpp"

namespace bms::hal::cortex_m {

/// MPS2 system clock: SysTick's processor clock source. QEMU's mps2 machines run it at
/// 25 MHz; with -icount shift=0 (1 ns per instruction) one count is 40 instructions.
inline constexpr std::uint32_t kSysClockHz = 25'000'000u;
inline constexpr std::uint64_t kNsPerCount = 1'000'000'000u / kSysClockHz;
static_assert(1'000'000'000u % kSysClockHz == 0u, "the clock period must be a whole number of ns");

/// SysTick on the processor clock, reloading once per tick period: each reload is one tick
/// and one interrupt, counted by SysTick_Handler. The 64-bit count of clock cycles since
/// construction is (interrupts * period) + (counts into the current period).
/// Owns SysTick: construct one per program (later constructions restart the count).
class SysTickTimer final : public MonotonicClock, public TickSource {
 public:
  /// Starts SysTick. The period must be a whole number of clock counts in 1..2^24
  /// (0.2 s = 5 000 000 counts); otherwise ok() is false and SysTick stays off.
  explicit SysTickTimer(std::uint64_t period_ns = kTickPeriodNs);

  bool ok() const { return reload_ != 0u; }

  /// Clock counts (kSysClockHz) since construction; exact, never goes backwards.
  std::uint64_t now_counts() const;
  /// now_counts() in ns (resolution kNsPerCount).
  std::uint64_t now_ns() const override { return now_counts() * kNsPerCount; }

  /// Sleeps (WFI) until the next SysTick reload. Tick 0 is the first reload after
  /// construction. timeout_ms is checked at each interrupt, so it is rounded up to a period.
  Status wait_next_tick(std::uint32_t& tick, std::int32_t timeout_ms) override;
  std::uint64_t period_ns() const override { return period_ns_; }
  std::uint32_t missed_ticks() const override { return missed_; }
  const char* last_error() const override { return error_; }

 private:
  std::uint32_t elapsed_periods() const;

  std::uint64_t period_ns_;
  std::uint32_t reload_ = 0u;  // counts per period - 1; 0 when not running
  std::uint32_t next_tick_ = 0u;
  std::uint32_t missed_ = 0u;
  const char* error_ = "";
  mutable std::uint64_t last_counts_ = 0u;  // now_counts() never returns less than this
};

/// Log lines on the semihosting console: "level: message" or, with a clock,
/// "[seconds.micros] level: message".
class SemihostLogSink final : public LogSink {
 public:
  explicit SemihostLogSink(LogLevel min_level = LogLevel::info, const MonotonicClock* clock = nullptr)
      : min_level_(min_level), clock_(clock) {}
  void write(LogLevel level, const char* message) override;

 private:
  LogLevel min_level_;
  const MonotonicClock* clock_;
};

/// NonVolatileMemory over RAM: the portable one (bms/hal/ram_nvm.hpp), over retained_ram() here.
using RamNvm = bms::hal::RamNvm;

/// The CMSDK APB watchdog of the MPS2 boards (0x40008000, clocked at kSysClockHz). Its
/// counter runs down from the load value; at zero it raises its interrupt (the NMI on MPS2)
/// and reloads, and at the second zero without a kick it resets the chip. start() checks the
/// peripheral's identification registers: without the device (another board, another
/// emulator) present() is false and kick() only counts.
class CmsdkWatchdog final : public Watchdog {
 public:
  static constexpr std::uintptr_t kBase = 0x40008000u;

  /// Arms the watchdog with a deadline of timeout_ms (at most 171 s at 25 MHz).
  void start(std::uint32_t timeout_ms);
  void kick() override;
  std::uint32_t timeout_ms() const override { return timeout_ms_; }
  bool present() const { return present_; }
  std::uint32_t kicks() const { return kicks_; }
  /// The counter's value now (0 without the device): after a kick it is near the load value.
  std::uint32_t counter() const;

 private:
  std::uint32_t timeout_ms_ = 0u;
  std::uint32_t kicks_ = 0u;
  bool present_ = false;
};

/// RAM that Reset_Handler neither copies nor zeroes (.noinit): a warm reset keeps it.
inline constexpr std::size_t kRetainedRamBytes = 4096u;
std::uint8_t* retained_ram();

}  // namespace bms::hal::cortex_m
