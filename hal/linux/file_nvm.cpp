#include "bms/hal/linux/file_nvm.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>

#include "errno_text.hpp"

namespace bms::hal::lnx {

FileNvm::~FileNvm() { close(); }

void FileNvm::close() {
  if (fd_ >= 0) ::close(fd_);
  fd_ = -1;
}

Status FileNvm::fail(Status s, const char* what, int err) {
  char text[96];
  // snprintf's result is not needed: a message longer than the buffer is cut, on purpose.
  (void)std::snprintf(error_, sizeof error_, "NVM file '%s': %s%s%s", path_, what, err != 0 ? ": " : "",
                      err != 0 ? detail::errno_text(err, text, sizeof text) : "");
  return s;
}

Status FileNvm::pwrite_all(std::size_t offset, const void* src, std::size_t len) {
  const auto* p = static_cast<const unsigned char*>(src);
  while (len > 0) {
    const ssize_t n = ::pwrite(fd_, p, len, static_cast<off_t>(offset));
    if (n < 0) {
      if (errno == EINTR) continue;
      return fail(Status::io_error, "pwrite failed", errno);
    }
    p += n;
    offset += static_cast<std::size_t>(n);
    len -= static_cast<std::size_t>(n);
  }
  return Status::ok;
}

Status FileNvm::open(const char* path, std::size_t size_bytes, std::size_t page_size) {
  close();
  (void)std::snprintf(path_, sizeof path_, "%s", path != nullptr ? path : "");
  if (path == nullptr || path[0] == '\0') return fail(Status::invalid_argument, "empty path", 0);
  if (page_size == 0 || size_bytes == 0 || size_bytes % page_size != 0)
    return fail(Status::invalid_argument, "size must be a positive multiple of the page size", 0);
  page_size_ = page_size;
  int fd = ::open(path, O_RDWR | O_CLOEXEC);
  if (fd < 0 && errno == ENOENT) {
    const Status c = create_erased(path, size_bytes);
    if (c != Status::ok) return c;
    fd = ::open(path, O_RDWR | O_CLOEXEC);
  }
  if (fd < 0) return fail(errno == ENOENT ? Status::not_found : Status::io_error, "open failed", errno);
  struct stat st {};
  if (::fstat(fd, &st) < 0) {
    const int err = errno;
    ::close(fd);
    return fail(Status::io_error, "fstat failed", err);
  }
  fd_ = fd;
  size_ = size_bytes;
  page_size_ = page_size;
  if (st.st_size == 0) {
    const Status s = erase(0, size_bytes);
    if (s != Status::ok) {
      close();
      return s;
    }
  } else if (static_cast<std::size_t>(st.st_size) != size_bytes) {
    close();
    char what[96];
    (void)std::snprintf(what, sizeof what, "has %lld bytes, expected %zu", static_cast<long long>(st.st_size), size_bytes);
    return fail(Status::invalid_argument, what, 0);
  }
  return Status::ok;
}

// Fills PATH.creating with erased bytes, syncs it and renames it to PATH: the rename is the
// commit, so no reader ever sees a partly filled file under PATH.
Status FileNvm::create_erased(const char* path, std::size_t size_bytes) {
  char tmp[sizeof path_ + 16];
  (void)std::snprintf(tmp, sizeof tmp, "%s.creating", path);
  const int fd = ::open(tmp, O_RDWR | O_CREAT | O_TRUNC | O_CLOEXEC, 0644);
  if (fd < 0) return fail(errno == ENOENT ? Status::not_found : Status::io_error, "cannot create", errno);
  fd_ = fd;
  size_ = size_bytes;
  Status s = erase(0, size_bytes);
  fd_ = -1;
  if (::close(fd) != 0 && s == Status::ok) s = fail(Status::io_error, "close failed", errno);
  if (s == Status::ok && ::rename(tmp, path) != 0) s = fail(Status::io_error, "rename failed", errno);
  if (s != Status::ok) {
    (void)::unlink(tmp);
    return s;
  }
  // The directory entry itself must be durable too.
  char dir[sizeof path_];
  (void)std::snprintf(dir, sizeof dir, "%s", path);
  char* slash = std::strrchr(dir, '/');
  if (slash == nullptr) {
    dir[0] = '.';
    dir[1] = '\0';
  } else {
    slash[slash == dir ? 1 : 0] = '\0';
  }
  const int dfd = ::open(dir, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dfd >= 0) {
    (void)::fsync(dfd);
    (void)::close(dfd);
  }
  return Status::ok;
}

Status FileNvm::read(std::size_t offset, void* dst, std::size_t len) {
  if (fd_ < 0) return fail(Status::not_open, "not open", 0);
  if (!span_fits(offset, len, size_)) return fail(Status::out_of_range, "read outside the device", 0);
  auto* p = static_cast<unsigned char*>(dst);
  while (len > 0) {
    const ssize_t n = ::pread(fd_, p, len, static_cast<off_t>(offset));
    if (n < 0) {
      if (errno == EINTR) continue;
      return fail(Status::io_error, "pread failed", errno);
    }
    if (n == 0) return fail(Status::io_error, "file shorter than expected", 0);
    p += n;
    offset += static_cast<std::size_t>(n);
    len -= static_cast<std::size_t>(n);
  }
  return Status::ok;
}

Status FileNvm::write(std::size_t offset, const void* src, std::size_t len) {
  if (fd_ < 0) return fail(Status::not_open, "not open", 0);
  if (!span_fits(offset, len, size_)) return fail(Status::out_of_range, "write outside the device", 0);
  const Status s = pwrite_all(offset, src, len);
  if (s != Status::ok) return s;
  if (::fsync(fd_) < 0) return fail(Status::io_error, "fsync failed", errno);
  return Status::ok;
}

Status FileNvm::erase(std::size_t offset, std::size_t len) {
  if (fd_ < 0) return fail(Status::not_open, "not open", 0);
  if (offset % page_size_ != 0 || len % page_size_ != 0)
    return fail(Status::invalid_argument, "erase not page-aligned", 0);
  if (!span_fits(offset, len, size_)) return fail(Status::out_of_range, "erase outside the device", 0);
  unsigned char ff[512];
  std::memset(ff, kNvmErasedByte, sizeof ff);
  while (len > 0) {
    const std::size_t chunk = len < sizeof ff ? len : sizeof ff;
    const Status s = pwrite_all(offset, ff, chunk);
    if (s != Status::ok) return s;
    offset += chunk;
    len -= chunk;
  }
  if (::fsync(fd_) < 0) return fail(Status::io_error, "fsync failed", errno);
  return Status::ok;
}

}  // namespace bms::hal::lnx
