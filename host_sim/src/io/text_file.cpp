#include "io/text_file.hpp"

#include <fmt/format.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <algorithm>
#include <mutex>
#include <utility>

#include "io/input_error.hpp"

namespace bms {

namespace {
std::vector<std::filesystem::path>& inputs() {
  static std::vector<std::filesystem::path> files;
  return files;
}
// A study's worker threads read their cell files at once (`study blind --cell X`).
std::mutex& inputs_mutex() {
  static std::mutex m;
  return m;
}
void note_input(std::filesystem::path p) {
  const std::lock_guard<std::mutex> lock(inputs_mutex());
  inputs().push_back(std::move(p));
}
}  // namespace

const std::vector<std::filesystem::path>& input_files_read() { return inputs(); }

std::string read_text_file(const std::filesystem::path& file, std::uintmax_t max_bytes) {
  std::error_code ec;
  const auto st = std::filesystem::status(file, ec);
  if (std::filesystem::is_directory(st)) {
    throw InputError(fmt::format("{}: cannot read: is a directory", file.string()));
  }
  if (std::filesystem::exists(st) && !std::filesystem::is_regular_file(st)) {
    throw InputError(fmt::format("{}: cannot read: not a regular file (a device, FIFO or socket)", file.string()));
  }
  const std::uintmax_t size = std::filesystem::file_size(file, ec);
  if (ec) throw InputError(fmt::format("{}: cannot read: {}", file.string(), ec.message()));
  if (size > max_bytes) {
    throw InputError(fmt::format("{}: {} bytes, larger than the {} bytes an input may have", file.string(), size,
                                 max_bytes));
  }
  std::ifstream in(file, std::ios::binary);
  note_input(std::filesystem::weakly_canonical(std::filesystem::absolute(file, ec), ec));
  if (!in) {
    throw InputError(fmt::format("{}: cannot read: {}", file.string(), std::strerror(errno)));
  }
  // Read at most max_bytes + 1, in case the file grows while it is read.
  std::string text(std::min(size, max_bytes) + 1, '\0');
  in.read(text.data(), static_cast<std::streamsize>(text.size()));
  text.resize(static_cast<size_t>(in.gcount()));
  if (text.size() > max_bytes) {
    throw InputError(fmt::format("{}: larger than the {} bytes an input may have", file.string(), max_bytes));
  }
  if (in.bad()) {
    throw InputError(fmt::format("{}: read error: {}", file.string(), std::strerror(errno)));
  }
  return text;
}

}  // namespace bms
