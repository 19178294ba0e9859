// RAM-backed NVM for unit tests, with a power-loss simulation: tear_next_write_at(n)
// makes the next write store only its first n bytes and return Status::io_error, as if
// power failed part-way through; the rest of the span keeps its old contents.
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include "bms/hal/nvm.hpp"

namespace bms::hal::fake {

class RamNvm final : public NonVolatileMemory {
 public:
  /// size_bytes must be a multiple of page_size; starts erased.
  RamNvm(std::size_t size_bytes, std::size_t page_size);

  std::size_t size_bytes() const override { return mem_.size(); }
  std::size_t page_size() const override { return page_size_; }
  Status read(std::size_t offset, void* dst, std::size_t len) override;
  Status write(std::size_t offset, const void* src, std::size_t len) override;
  Status erase(std::size_t offset, std::size_t len) override;
  const char* last_error() const override { return last_error_.c_str(); }

  /// The next write lands only bytes [0, n) of its data (n may exceed the length: then
  /// the whole write lands and it still reports io_error) and returns io_error.
  void tear_next_write_at(std::size_t n) {
    tear_armed_ = true;
    tear_at_ = n;
  }
  /// The next erase fails with io_error and leaves the memory unchanged.
  void fail_next_erase() { fail_erase_ = true; }

  const std::vector<std::uint8_t>& bytes() const { return mem_; }
  std::uint32_t writes() const { return writes_; }
  std::uint32_t erases() const { return erases_; }
  std::uint32_t torn_writes() const { return torn_writes_; }

 private:
  std::vector<std::uint8_t> mem_;
  std::size_t page_size_;
  bool tear_armed_ = false;
  std::size_t tear_at_ = 0;
  bool fail_erase_ = false;
  std::uint32_t writes_ = 0;
  std::uint32_t erases_ = 0;
  std::uint32_t torn_writes_ = 0;
  std::string last_error_;
};

}  // namespace bms::hal::fake
