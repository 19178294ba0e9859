// NVM emulated by a file of fixed size: pread for reads, pwrite + fsync for writes and
// erases (a write is durable when it returns ok). A missing file is created erased (0xFF)
// atomically: filled under the name PATH.creating, synced, then renamed to PATH, so a
// process killed while creating it leaves either no file or a whole erased one.
#pragma once

#include <cstddef>
#include <cstdint>

#include "bms/hal/nvm.hpp"

namespace bms::hal::lnx {

class FileNvm final : public NonVolatileMemory {
 public:
  FileNvm() = default;
  ~FileNvm();
  FileNvm(const FileNvm&) = delete;
  FileNvm& operator=(const FileNvm&) = delete;

  /// Open or create `path`. A missing file is created filled with kNvmErasedByte up to
  /// size_bytes (atomically, see above); an empty one (left by an older build killed while
  /// creating it) is filled the same way; an existing file of another size is refused
  /// (invalid_argument), as is a size that is not a positive multiple of page_size.
  Status open(const char* path, std::size_t size_bytes, std::size_t page_size);
  void close();
  bool is_open() const { return fd_ >= 0; }

  std::size_t size_bytes() const override { return size_; }
  std::size_t page_size() const override { return page_size_; }
  Status read(std::size_t offset, void* dst, std::size_t len) override;
  Status write(std::size_t offset, const void* src, std::size_t len) override;
  Status erase(std::size_t offset, std::size_t len) override;
  const char* last_error() const override { return error_; }

 private:
  Status fail(Status s, const char* what, int err);
  Status pwrite_all(std::size_t offset, const void* src, std::size_t len);
  Status create_erased(const char* path, std::size_t size_bytes);
  int fd_ = -1;
  std::size_t size_ = 0;
  std::size_t page_size_ = 1;
  char path_[200] = "";
  char error_[320] = "";
};

}  // namespace bms::hal::lnx
