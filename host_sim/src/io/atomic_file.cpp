#include "io/atomic_file.hpp"

#include <cerrno>
#include <cstring>
#include <stdexcept>
#include <system_error>

#include <fmt/format.h>

#include "io/input_error.hpp"

namespace bms {

AtomicFileWriter::AtomicFileWriter(std::filesystem::path file) : file_(std::move(file)), tmp_(file_) {
  tmp_ += ".tmp";
  out_ = std::fopen(tmp_.c_str(), "wb");
  if (out_ == nullptr) {
    throw InputError(fmt::format("{}: cannot create: {}", tmp_.string(), std::strerror(errno)));
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
  if (std::fwrite(buffer_.data(), 1, buffer_.size(), out_) != buffer_.size()) {
    throw RuntimeFailure(fmt::format("{}: write failed: {}", tmp_.string(), std::strerror(errno)));
  }
  buffer_.clear();
}

void AtomicFileWriter::commit() {
  if (out_ == nullptr) throw std::logic_error(file_.string() + ": committed twice");
  flush();
  const bool closed = std::fclose(out_) == 0;
  out_ = nullptr;
  std::error_code ec;
  if (!closed) {
    std::filesystem::remove(tmp_, ec);
    throw RuntimeFailure(fmt::format("{}: write failed: {}", tmp_.string(), std::strerror(errno)));
  }
  std::filesystem::rename(tmp_, file_, ec);
  if (ec) {
    const std::string reason = ec.message();
    std::filesystem::remove(tmp_, ec);
    throw RuntimeFailure(fmt::format("{}: cannot rename to {}: {}", tmp_.string(), file_.string(), reason));
  }
}

}  // namespace bms
