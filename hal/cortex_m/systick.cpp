// SysTick tick source and monotonic clock (see board.hpp).
#include <cstdint>

#include "bms/hal/cortex_m/board.hpp"

namespace {

// Armv7-M system registers.
constexpr std::uintptr_t kSystCsr = 0xE000E010u;
constexpr std::uintptr_t kSystRvr = 0xE000E014u;
constexpr std::uintptr_t kSystCvr = 0xE000E018u;
constexpr std::uintptr_t kScbIcsr = 0xE000ED04u;
constexpr std::uint32_t kCsrEnable = 1u << 0;
constexpr std::uint32_t kCsrTickInt = 1u << 1;
constexpr std::uint32_t kCsrProcessorClock = 1u << 2;
constexpr std::uint32_t kIcsrPendStSet = 1u << 26;
constexpr std::uint32_t kIcsrPendStClr = 1u << 25;
constexpr std::uint64_t kMaxCounts = 1u << 24;

inline volatile std::uint32_t& reg(std::uintptr_t address) {
  return *reinterpret_cast<volatile std::uint32_t*>(address);
}

// SysTick reloads since the timer was started; written only by SysTick_Handler.
volatile std::uint32_t g_periods = 0u;

}  // namespace

extern "C" void SysTick_Handler() { g_periods = g_periods + 1u; }

namespace bms::hal::cortex_m {

SysTickTimer::SysTickTimer(std::uint64_t period_ns) : period_ns_(period_ns) {
  reg(kSystCsr) = 0u;
  const std::uint64_t counts = period_ns / kNsPerCount;
  if (period_ns % kNsPerCount != 0u || counts == 0u || counts > kMaxCounts) {
    error_ = "SysTick: period is not a whole number of clock counts in 1..2^24";
    return;
  }
  reload_ = static_cast<std::uint32_t>(counts - 1u);
  reg(kSystRvr) = reload_;
  reg(kSystCvr) = 0u;  // any write clears the counter; it reloads on the next clock
  reg(kSystCsr) = kCsrEnable | kCsrProcessorClock;
  // The origin of the count is the first reload: wait for it (a few clocks at most).
  for (int i = 0; reg(kSystCvr) == 0u; ++i) {
    if (i > 100000) {
      reg(kSystCsr) = 0u;
      reload_ = 0u;
      error_ = "SysTick: the counter does not run";
      return;
    }
  }
  reg(kScbIcsr) = kIcsrPendStClr;
  g_periods = 0u;
  reg(kSystCsr) = kCsrEnable | kCsrTickInt | kCsrProcessorClock;
}

std::uint32_t SysTickTimer::elapsed_periods() const { return g_periods; }

std::uint64_t SysTickTimer::now_counts() const {
  if (reload_ == 0u) return 0u;
  std::uint32_t primask = 0u;
  __asm volatile("mrs %0, primask\n\tcpsid i" : "=r"(primask)::"memory");
  std::uint32_t periods = g_periods;
  std::uint32_t value = reg(kSystCvr);
  if ((reg(kScbIcsr) & kIcsrPendStSet) != 0u) {  // reloaded, interrupt not taken yet
    ++periods;
    value = reg(kSystCvr);
  }
  __asm volatile("msr primask, %0" ::"r"(primask) : "memory");
  const std::uint64_t period = static_cast<std::uint64_t>(reload_) + 1u;
  std::uint64_t now = static_cast<std::uint64_t>(periods) * period + (reload_ - value);
  // QEMU's SysTick can show the reloaded counter a few instructions before it sets the pending
  // bit (measured under -icount: one tick of a replay read a whole period, 200 000 000 counts,
  // too few and the next one too many). Such a read is below the last one by almost a period:
  // it belongs to the next period.
  if (now < last_counts_) now += period;
  last_counts_ = now;
  return now;
}

Status SysTickTimer::wait_next_tick(std::uint32_t& tick, std::int32_t timeout_ms) {
  if (reload_ == 0u) {
    return Status::not_open;
  }
  const std::uint64_t start = now_counts();
  const std::uint64_t limit =
      timeout_ms > 0 ? static_cast<std::uint64_t>(timeout_ms) * (kSysClockHz / 1000u) : 0u;
  while (elapsed_periods() < next_tick_ + 1u) {
    if (timeout_ms == 0 || (timeout_ms > 0 && now_counts() - start >= limit)) {
      return Status::timeout;
    }
    __asm volatile("wfi" ::: "memory");
  }
  const std::uint32_t latest = elapsed_periods() - 1u;
  missed_ += latest - next_tick_;
  tick = latest;
  next_tick_ = latest + 1u;
  return Status::ok;
}

}  // namespace bms::hal::cortex_m
