// NonVolatileMemory over RAM (see board.hpp).
#include <cstring>

#include "bms/hal/cortex_m/board.hpp"

namespace {
// In .noinit: Reset_Handler does not zero it, so a warm reset keeps the contents.
__attribute__((section(".noinit"))) std::uint8_t g_retained[bms::hal::cortex_m::kRetainedRamBytes];
}  // namespace

namespace bms::hal::cortex_m {

std::uint8_t* retained_ram() { return g_retained; }

RamNvm::RamNvm(std::uint8_t* storage, std::size_t size_bytes, std::size_t page_size)
    : mem_(storage),
      size_(storage != nullptr ? size_bytes : 0u),
      page_size_(page_size == 0u ? 1u : page_size) {}

Status RamNvm::read(std::size_t offset, void* dst, std::size_t len) {
  if (!span_fits(offset, len, size_)) {
    error_ = "RAM NVM: read outside the device";
    return Status::out_of_range;
  }
  if (len > 0u) std::memcpy(dst, mem_ + offset, len);
  return Status::ok;
}

Status RamNvm::write(std::size_t offset, const void* src, std::size_t len) {
  if (!span_fits(offset, len, size_)) {
    error_ = "RAM NVM: write outside the device";
    return Status::out_of_range;
  }
  if (len > 0u) std::memcpy(mem_ + offset, src, len);
  return Status::ok;
}

Status RamNvm::erase(std::size_t offset, std::size_t len) {
  if (offset % page_size_ != 0u || len % page_size_ != 0u) {
    error_ = "RAM NVM: erase not page-aligned";
    return Status::invalid_argument;
  }
  if (!span_fits(offset, len, size_)) {
    error_ = "RAM NVM: erase outside the device";
    return Status::out_of_range;
  }
  if (len > 0u) std::memset(mem_ + offset, kNvmErasedByte, len);
  return Status::ok;
}

}  // namespace bms::hal::cortex_m
