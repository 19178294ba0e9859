// NonVolatileMemory over a caller-provided RAM buffer, with the erase semantics of flash
// (erased bytes read kNvmErasedByte). Constructing one does not erase the buffer: on the board
// the buffer is its retained RAM, whose contents survive a warm reset. Used by the board
// (hal/cortex_m), the board application's host build (target/platform_host.cpp) and
// bms-firmware without --nvm. Portable: no heap; header-only.
#pragma once

#include <cstddef>
#include <cstdint>
#include <cstring>

#include "bms/hal/nvm.hpp"

namespace bms::hal {

class RamNvm final : public NonVolatileMemory {
 public:
  RamNvm(std::uint8_t* storage, std::size_t size_bytes, std::size_t page_size)
      : mem_(storage), size_(storage != nullptr ? size_bytes : 0u), page_size_(page_size == 0u ? 1u : page_size) {}

  std::size_t size_bytes() const override { return size_; }
  std::size_t page_size() const override { return page_size_; }
  const char* last_error() const override { return error_; }

  Status read(std::size_t offset, void* dst, std::size_t len) override {
    if (!span_fits(offset, len, size_)) return fail("RAM NVM: read outside the device", Status::out_of_range);
    if (len > 0u) std::memcpy(dst, mem_ + offset, len);
    return Status::ok;
  }

  Status write(std::size_t offset, const void* src, std::size_t len) override {
    if (!span_fits(offset, len, size_)) return fail("RAM NVM: write outside the device", Status::out_of_range);
    if (len > 0u) std::memcpy(mem_ + offset, src, len);
    return Status::ok;
  }

  Status erase(std::size_t offset, std::size_t len) override {
    if (offset % page_size_ != 0u || len % page_size_ != 0u)
      return fail("RAM NVM: erase not page-aligned", Status::invalid_argument);
    if (!span_fits(offset, len, size_)) return fail("RAM NVM: erase outside the device", Status::out_of_range);
    if (len > 0u) std::memset(mem_ + offset, kNvmErasedByte, len);
    return Status::ok;
  }

 private:
  Status fail(const char* why, Status s) {
    error_ = why;
    return s;
  }

  std::uint8_t* mem_;
  std::size_t size_;
  std::size_t page_size_;
  const char* error_ = "";
};

}  // namespace bms::hal
