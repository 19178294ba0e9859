#pragma once
// Writes FILE.tmp and renames it to FILE only in commit(), so an interrupted run never leaves
// a complete-looking FILE; without commit() the destructor deletes FILE.tmp. Text is
// buffered and written in 64 KiB blocks. Shared by every writer of the host tools.
#include <cstdio>
#include <filesystem>
#include <string>
#include <string_view>

#include "io/input_error.hpp"

namespace bms {

// A file that could not be written for lack of room or on a read-only disk (ENOSPC, EDQUOT,
// EROFS): a runtime failure (exit 1) whose message says what happened and what to try, e.g.
// "no space left on device writing out/run/truth.csv: free space or choose --out on another disk"
// (the file is named where it would have ended up, not in the staging folder).
class WriteFailure : public RuntimeFailure {
 public:
  using RuntimeFailure::RuntimeFailure;
};
// Throws WriteFailure for those errno values, RuntimeFailure "FILE: DOING: strerror" otherwise.
[[noreturn]] void throw_write_failure(const std::filesystem::path& file, int err, const char* doing);

class AtomicFileWriter {
 public:
  // Throws InputError when FILE.tmp cannot be created (WriteFailure on a full or read-only disk).
  explicit AtomicFileWriter(std::filesystem::path file);
  ~AtomicFileWriter();
  AtomicFileWriter(const AtomicFileWriter&) = delete;
  AtomicFileWriter& operator=(const AtomicFileWriter&) = delete;

  void append(std::string_view text);  // std::logic_error after commit()
  void commit();                       // RuntimeFailure when writing or renaming fails
  const std::filesystem::path& path() const { return file_; }

 private:
  void flush();
  std::filesystem::path file_;
  std::filesystem::path tmp_;
  std::FILE* out_ = nullptr;
  std::string buffer_;
};

}  // namespace bms
