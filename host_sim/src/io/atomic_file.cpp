#include "io/atomic_file.hpp"

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <system_error>

#include <fmt/format.h>

#include "io/input_error.hpp"

namespace bms {

namespace {

bool no_room(int err) { return err == ENOSPC || err == EDQUOT || err == EROFS; }

// FILE as the user will look for it: in DIR, not in its staging folder DIR.partial-N.
std::string shown(const std::filesystem::path& file) {
  const std::string folder = file.parent_path().filename().string();
  const auto dot = folder.rfind(".partial-");
  if (dot == std::string::npos || dot == 0 || dot + 9 == folder.size() ||
      folder.find_first_not_of("0123456789", dot + 9) != std::string::npos)
    return file.string();
  return (file.parent_path().parent_path() / folder.substr(0, dot) / file.filename()).string();
}

}  // namespace

void throw_write_failure(const std::filesystem::path& file, int err, const char* doing) {
  const std::string f = shown(file);
  switch (err) {
    case ENOSPC: throw WriteFailure("no space left on device writing " + f + ": free space or choose --out on another disk");
    case EDQUOT:
      throw WriteFailure("disk quota exceeded writing " + f + ": free space (or raise the quota) or choose --out on another disk");
    case EROFS: throw WriteFailure("read-only file system writing " + f + ": choose --out on a writable disk");
    default: throw RuntimeFailure(fmt::format("{}: {}: {}", f, doing, std::strerror(err)));
  }
}

AtomicFileWriter::AtomicFileWriter(std::filesystem::path file) : file_(std::move(file)), tmp_(file_) {
  tmp_ += ".tmp";
  out_ = std::fopen(tmp_.c_str(), "wb");
  if (out_ == nullptr) {
    const int err = errno;
    if (no_room(err)) throw_write_failure(file_, err, "cannot create");
    throw InputError(fmt::format("{}: cannot create: {}", tmp_.string(), std::strerror(err)));
  }
}

AtomicFileWriter::~AtomicFileWriter() {
  if (out_ != nullptr) {
    std::fclose(out_);
    std::error_code ignored;
    std::filesystem::remove(tmp_, ignored);
  }
}

void AtomicFileWriter::append(std::string_view text) {
  if (out_ == nullptr) throw std::logic_error(file_.string() + ": written after commit()");
  buffer_.append(text);
  constexpr std::size_t kFlushBytes = 1 << 16;
  if (buffer_.size() >= kFlushBytes) flush();
}

void AtomicFileWriter::flush() {
  if (std::fwrite(buffer_.data(), 1, buffer_.size(), out_) != buffer_.size()) throw_write_failure(file_, errno, "write failed");
  buffer_.clear();
}

void AtomicFileWriter::commit() {
  if (out_ == nullptr) throw std::logic_error(file_.string() + ": committed twice");
  flush();
  const bool closed = std::fclose(out_) == 0;
  out_ = nullptr;
  std::error_code ec;
  if (!closed) {
    const int err = errno;
    std::filesystem::remove(tmp_, ec);
    throw_write_failure(file_, err, "write failed");
  }
  std::filesystem::rename(tmp_, file_, ec);
  if (ec) {
    const std::error_code failed = ec;
    std::filesystem::remove(tmp_, ec);
    if (no_room(failed.value())) throw_write_failure(file_, failed.value(), "cannot rename");
    throw RuntimeFailure(fmt::format("{}: cannot rename to {}: {}", tmp_.string(), file_.string(), failed.message()));
  }
}

}  // namespace bms
