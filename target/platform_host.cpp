// Host (Linux) side of platform.hpp: no instruction counter; a counting watchdog and an
// array as non-volatile memory.
#include "platform.hpp"

#include "bms/hal/nvm.hpp"
#include "bms/hal/watchdog.hpp"

#include <cstdio>
#include <cstring>

namespace bms::target {

namespace {

class CountingWatchdog final : public bms::hal::Watchdog {
 public:
  void kick() override { ++kicks; }
  std::uint32_t kicks = 0;
};

// The board's RamNvm over its 4 KiB of retained RAM, as an array.
class ArrayNvm final : public bms::hal::NonVolatileMemory {
 public:
  std::size_t size_bytes() const override { return sizeof bytes_; }
  std::size_t page_size() const override { return kPage; }
  bms::hal::Status read(std::size_t off, void* dst, std::size_t len) override {
    if (!span_fits(off, len, sizeof bytes_)) return bms::hal::Status::out_of_range;
    std::memcpy(dst, bytes_ + off, len);
    return bms::hal::Status::ok;
  }
  bms::hal::Status write(std::size_t off, const void* src, std::size_t len) override {
    if (!span_fits(off, len, sizeof bytes_)) return bms::hal::Status::out_of_range;
    std::memcpy(bytes_ + off, src, len);
    return bms::hal::Status::ok;
  }
  bms::hal::Status erase(std::size_t off, std::size_t len) override {
    if (off % kPage != 0u || len % kPage != 0u) return bms::hal::Status::invalid_argument;
    if (!span_fits(off, len, sizeof bytes_)) return bms::hal::Status::out_of_range;
    std::memset(bytes_ + off, bms::hal::kNvmErasedByte, len);
    return bms::hal::Status::ok;
  }

 private:
  static constexpr std::size_t kPage = 256;
  unsigned char bytes_[4096];
};

CountingWatchdog g_watchdog;

}  // namespace

void platform_start() {}
std::uint64_t platform_instructions() { return 0u; }
void platform_report() { std::printf("# platform host\n"); }

bms::hal::Watchdog& platform_watchdog(std::uint32_t) { return g_watchdog; }
std::uint32_t platform_watchdog_kicks() { return g_watchdog.kicks; }
const char* platform_watchdog_kind() { return "counting"; }

bms::hal::NonVolatileMemory& platform_nvm() {
  static ArrayNvm nvm;
  static const bool erased = nvm.erase(0, nvm.size_bytes()) == bms::hal::Status::ok;
  (void)erased;
  return nvm;
}

}  // namespace bms::target
