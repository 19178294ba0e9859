// Self-test of the MPS2 board support (hal/cortex_m), run by ctest under QEMU:
//   - SysTick counts instructions under -icount shift=0: a loop of known length measures
//     within a few counts of its instruction count;
//   - the tick source delivers consecutive ticks 0.2 s of virtual time apart;
//   - the RAM NVM behaves like the NonVolatileMemory contract (erase, write, read, bounds);
//   - the semihosting log sink writes lines (this output).
// No libc stdio: every line goes through SemihostLogSink. Exit status: number of failures.
#include <bms/hal/cortex_m/board.hpp>
#include <cstdint>
#include <cstring>

namespace {

using bms::hal::LogLevel;
using bms::hal::LogLine;
using bms::hal::Status;
namespace cm = bms::hal::cortex_m;

// Runs `iterations` x 2 instructions (subs, bne), plus 1 for the mov.
void __attribute__((noinline)) spin(std::uint32_t iterations) {
  __asm volatile(
      "mov r0, %0\n"
      "1: subs r0, r0, #1\n"
      "bne 1b\n"
      :
      : "r"(iterations)
      : "r0", "cc");
}

struct Checker {
  cm::SemihostLogSink& log;
  int failures = 0;
  void check(bool ok, const char* what) {
    LogLine l;
    l.add(ok ? "pass: " : "FAIL: ").add(what);
    log.write(ok ? LogLevel::info : LogLevel::error, l.c_str());
    if (!ok) ++failures;
  }
};

}  // namespace

int main() {
  cm::SemihostLogSink log(LogLevel::debug);
  Checker c{log};
  cm::SysTickTimer timer;
  c.check(timer.ok(), "SysTick starts with a 0.2 s period");

  // Instruction counting.
  const std::uint64_t a = timer.now_ns();
  const std::uint64_t b = timer.now_ns();
  const std::uint64_t overhead = b - a;
  const std::uint32_t n = 1'000'000u;
  const std::uint64_t t0 = timer.now_ns();
  spin(n);
  const std::uint64_t t1 = timer.now_ns();
  const std::uint64_t measured = t1 - t0;
  const std::uint64_t expected = 2u * static_cast<std::uint64_t>(n) + 1u;
  const std::uint64_t diff = measured > expected ? measured - expected : expected - measured;
  log.write(LogLevel::info, LogLine()
                                .add("spin loop: expected ")
                                .add(expected)
                                .add(" instructions, measured ")
                                .add(measured)
                                .add(" (counter overhead ")
                                .add(overhead)
                                .add(")")
                                .c_str());
  c.check(diff <= overhead + 2u * cm::kNsPerCount, "SysTick under -icount shift=0 counts instructions");
  c.check(timer.now_ns() >= t1, "the clock does not go backwards");

  // Tick source: two consecutive ticks, one period apart.
  std::uint32_t k0 = 0, k1 = 0;
  const bool got0 = timer.wait_next_tick(k0, -1) == Status::ok;
  const std::uint64_t w0 = timer.now_ns();
  const bool got1 = timer.wait_next_tick(k1, -1) == Status::ok;
  const std::uint64_t w1 = timer.now_ns();
  c.check(got0 && got1 && k1 == k0 + 1u, "wait_next_tick delivers consecutive ticks");
  const std::uint64_t gap = w1 - w0;
  log.write(LogLevel::info, LogLine().add("tick gap ").add(gap).add(" ns").c_str());
  c.check(gap + 100'000u >= timer.period_ns() && gap <= timer.period_ns() + 100'000u,
          "ticks are 0.2 s of virtual time apart");
  std::uint32_t k2 = 0;
  c.check(timer.wait_next_tick(k2, 0) == Status::timeout, "a poll right after a tick times out");

  // RAM NVM over the retained region.
  cm::RamNvm nvm(cm::retained_ram(), cm::kRetainedRamBytes, 256u);
  c.check(nvm.size_bytes() == cm::kRetainedRamBytes && nvm.page_size() == 256u, "NVM size and page");
  c.check(nvm.erase(0u, 512u) == Status::ok, "erase two pages");
  std::uint8_t buf[16] = {};
  c.check(nvm.read(0u, buf, sizeof buf) == Status::ok && buf[0] == bms::hal::kNvmErasedByte &&
              buf[15] == bms::hal::kNvmErasedByte,
          "erased bytes read 0xFF");
  const char text[] = "bms nvm record";
  c.check(nvm.write(300u, text, sizeof text) == Status::ok, "write");
  char back[sizeof text] = {};
  c.check(nvm.read(300u, back, sizeof back) == Status::ok && std::memcmp(back, text, sizeof text) == 0,
          "read back what was written");
  c.check(nvm.write(cm::kRetainedRamBytes - 4u, text, 8u) == Status::out_of_range, "write past the end");
  c.check(nvm.erase(10u, 256u) == Status::invalid_argument, "unaligned erase");

  log.write(c.failures == 0 ? LogLevel::info : LogLevel::error,
            LogLine().add("board self-test: ").add(static_cast<std::int32_t>(c.failures)).add(" failures").c_str());
  return c.failures;
}
