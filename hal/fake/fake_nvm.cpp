#include "bms/hal/fake/fake_nvm.hpp"

#include <algorithm>
#include <cstring>

namespace bms::hal::fake {

RamNvm::RamNvm(std::size_t size_bytes, std::size_t page_size)
    : mem_(size_bytes, kNvmErasedByte), page_size_(page_size == 0 ? 1 : page_size) {}

Status RamNvm::read(std::size_t offset, void* dst, std::size_t len) {
  if (!span_fits(offset, len, mem_.size())) {
    last_error_ = "RAM NVM: read outside the device";
    return Status::out_of_range;
  }
  if (len > 0) std::memcpy(dst, mem_.data() + offset, len);
  return Status::ok;
}

Status RamNvm::write(std::size_t offset, const void* src, std::size_t len) {
  if (!span_fits(offset, len, mem_.size())) {
    last_error_ = "RAM NVM: write outside the device";
    return Status::out_of_range;
  }
  ++writes_;
  std::size_t landed = len;
  const bool torn = tear_armed_;
  if (torn) {
    tear_armed_ = false;
    landed = std::min(len, tear_at_);
  }
  if (landed > 0) std::memcpy(mem_.data() + offset, src, landed);
  if (torn) {
    ++torn_writes_;
    last_error_ = "RAM NVM: simulated power loss during write";
    return Status::io_error;
  }
  return Status::ok;
}

Status RamNvm::erase(std::size_t offset, std::size_t len) {
  if (offset % page_size_ != 0 || len % page_size_ != 0) {
    last_error_ = "RAM NVM: erase not page-aligned";
    return Status::invalid_argument;
  }
  if (!span_fits(offset, len, mem_.size())) {
    last_error_ = "RAM NVM: erase outside the device";
    return Status::out_of_range;
  }
  if (fail_erase_) {
    fail_erase_ = false;
    last_error_ = "RAM NVM: simulated erase failure";
    return Status::io_error;
  }
  ++erases_;
  std::fill_n(mem_.begin() + static_cast<std::ptrdiff_t>(offset), len, kNvmErasedByte);
  return Status::ok;
}

}  // namespace bms::hal::fake
