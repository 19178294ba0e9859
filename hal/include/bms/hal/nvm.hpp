// Non-volatile memory: a byte-addressed region of fixed size, erased in pages.
// Erased bytes read as kNvmErasedByte. A write may be interrupted by a power loss: then
// a prefix of it has landed and the rest keeps its old contents (a "torn" write); users
// store records with a checksum and a sequence number to survive that.
#pragma once

#include <cstddef>
#include <cstdint>

#include "bms/hal/status.hpp"

namespace bms::hal {

inline constexpr std::uint8_t kNvmErasedByte = 0xFF;

class NonVolatileMemory {
 public:
  virtual std::size_t size_bytes() const = 0;
  virtual std::size_t page_size() const = 0;

  /// Copy `len` bytes at `offset` into `dst`. out_of_range if the span leaves the device.
  virtual Status read(std::size_t offset, void* dst, std::size_t len) = 0;

  /// Store `len` bytes at `offset`; durable when it returns ok. out_of_range if the span
  /// leaves the device; io_error when it failed part-way (contents of the span unknown).
  virtual Status write(std::size_t offset, const void* src, std::size_t len) = 0;

  /// Set whole pages to kNvmErasedByte. offset and len must be multiples of page_size()
  /// (invalid_argument otherwise).
  virtual Status erase(std::size_t offset, std::size_t len) = 0;

  virtual const char* last_error() const { return ""; }

 protected:
  NonVolatileMemory() = default;
  NonVolatileMemory(const NonVolatileMemory&) = default;
  NonVolatileMemory& operator=(const NonVolatileMemory&) = default;
  ~NonVolatileMemory() = default;

  /// Helper for implementations: does [offset, offset+len) fit in `size`?
  static constexpr bool span_fits(std::size_t offset, std::size_t len, std::size_t size) {
    return offset <= size && len <= size - offset;
  }
};

}  // namespace bms::hal
