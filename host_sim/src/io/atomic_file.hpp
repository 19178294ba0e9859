#pragma once
// Writes FILE.tmp and renames it to FILE only in commit(), so an interrupted run never leaves
// a complete-looking FILE; without commit() the destructor deletes FILE.tmp. Text is
// buffered and written in 64 KiB blocks. Shared by every writer of the host tools.
#include <cstdio>
#include <filesystem>
#include <string>
#include <string_view>

namespace bms {

class AtomicFileWriter {
 public:
  // Throws InputError when FILE.tmp cannot be created.
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
