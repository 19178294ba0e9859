#include "io/output_folder.hpp"

#include <unistd.h>

#include <string>
#include <system_error>

#include "io/input_error.hpp"

namespace bms {

namespace fs = std::filesystem;

namespace {

std::string with_suffix(const fs::path& dir, const char* what) {
  return dir.filename().string() + "." + what + "-" + std::to_string(static_cast<long>(getpid()));
}

// A folder a bmssim run may replace: empty, or files only with a summary.json among them
// (every command writes one; none writes subfolders).
bool replaceable(const fs::path& dir) {
  std::error_code ec;
  if (fs::is_empty(dir, ec) && !ec) return true;
  if (!fs::is_regular_file(dir / "summary.json", ec)) return false;
  for (const auto& entry : fs::directory_iterator(dir, ec))
    if (!entry.is_regular_file(ec)) return false;
  return !ec;
}

}  // namespace

OutputFolder::OutputFolder(fs::path dir, const char* option) : dir_(std::move(dir)) {
  const std::string name = std::string(option) + " '" + dir_.string() + "'";
  if (dir_.empty()) throw InputError(std::string(option) + ": empty path");
  dir_ = dir_.lexically_normal();
  if (dir_.filename().empty()) dir_ = dir_.parent_path();  // a trailing '/'
  if (dir_.filename() == "." || dir_.filename() == ".." || dir_ == dir_.root_path())
    throw InputError(name + ": name a folder of its own (it is replaced whole)");
  std::error_code ec;
  const auto st = fs::status(dir_, ec);
  if (fs::exists(st) && !fs::is_directory(st)) throw InputError(name + ": exists and is not a folder");
  if (fs::is_directory(st) && !replaceable(dir_))
    throw InputError(name + ": a folder that no bmssim run wrote (subfolders, or no summary.json); choose a new or empty folder");
  fs::path parent = dir_.parent_path();
  if (parent.empty()) parent = ".";
  fs::create_directories(parent, ec);
  if (ec) throw InputError(name + ": cannot create its parent folder: " + ec.message());
  staging_ = parent / with_suffix(dir_, "partial");
  fs::remove_all(staging_, ec);
  if (!fs::create_directory(staging_, ec) || ec)
    throw InputError(name + ": cannot write in " + parent.string() + (ec ? ": " + ec.message() : std::string()));
}

OutputFolder::~OutputFolder() {
  if (committed_) return;
  std::error_code ec;
  fs::remove_all(staging_, ec);
}

void OutputFolder::commit() {
  std::error_code ec;
  fs::path old;
  if (fs::exists(dir_, ec)) {
    old = dir_.parent_path().empty() ? fs::path(with_suffix(dir_, "old")) : dir_.parent_path() / with_suffix(dir_, "old");
    fs::rename(dir_, old, ec);
    if (ec) throw RuntimeFailure("cannot replace " + dir_.string() + ": " + ec.message());
  }
  fs::rename(staging_, dir_, ec);
  if (ec) throw RuntimeFailure("cannot move " + staging_.string() + " to " + dir_.string() + ": " + ec.message());
  committed_ = true;
  if (!old.empty()) fs::remove_all(old, ec);
}

}  // namespace bms
