#include "io/output_folder.hpp"

#include <unistd.h>

#include <cstdlib>
#include <fstream>
#include <iomanip>
#include <map>
#include <sstream>
#include <string>
#include <system_error>

#include "io/atomic_file.hpp"
#include "io/input_error.hpp"
#include "io/text_file.hpp"

namespace bms {

namespace fs = std::filesystem;

namespace {

long g_owner = 0;  // 0: this process

}  // namespace

void adopt_output_folder_owner() {
  const char* v = std::getenv(kOutputOwnerVariable);
  if (v == nullptr) return;
  char* end = nullptr;
  const long owner = std::strtol(v, &end, 10);
  if (end != v && *end == '\0' && owner > 0) g_owner = owner;
  unsetenv(kOutputOwnerVariable);  // not passed on to this process's own children
}

long output_folder_owner() { return g_owner > 0 ? g_owner : static_cast<long>(getpid()); }

namespace {

std::string with_suffix(const fs::path& dir, const char* what) {
  return dir.filename().string() + "." + what + "-" + std::to_string(output_folder_owner());
}

// Written by commit(): the name and size of every file the run wrote, one per line.
constexpr const char* kManifest = ".bmssim-files";

// A folder a bmssim run may replace: empty, or exactly the files a run wrote there (its
// manifest lists each with its size): a summary.json alone does not tell (a cycler export
// may carry its own), nor a file added or changed since.
bool replaceable(const fs::path& dir) {
  std::error_code ec;
  if (fs::is_empty(dir, ec) && !ec) return true;
  std::ifstream manifest(dir / kManifest);
  if (!manifest) return false;
  std::map<std::string, std::uintmax_t> listed;
  std::string name;
  std::uintmax_t size = 0;
  while (manifest >> std::quoted(name) >> size) listed[name] = size;
  for (const auto& entry : fs::directory_iterator(dir, ec)) {
    const std::string n = entry.path().filename().string();
    if (n == kManifest) continue;
    if (entry.is_symlink(ec) || !entry.is_regular_file(ec)) return false;
    const auto it = listed.find(n);
    if (it == listed.end() || it->second != entry.file_size(ec)) return false;
  }
  return !ec;
}

// The input read so far that lives in `dir` (or below it), or "".
std::string input_inside(const fs::path& dir) {
  std::error_code ec;
  const fs::path d = fs::weakly_canonical(fs::absolute(dir, ec), ec);
  for (const fs::path& f : input_files_read()) {
    auto fi = f.begin();
    bool inside = true;
    for (auto di = d.begin(); di != d.end() && inside; ++di, ++fi) inside = fi != f.end() && *fi == *di;
    if (inside && fi != f.end()) return f.string();
  }
  return {};
}

void write_manifest(const fs::path& staging) {
  std::error_code ec;
  std::ostringstream list;
  for (const auto& entry : fs::directory_iterator(staging, ec))
    if (entry.is_regular_file(ec) && entry.path().filename() != kManifest)
      list << std::quoted(entry.path().filename().string()) << ' ' << entry.file_size(ec) << '\n';
  AtomicFileWriter out(staging / kManifest);
  out.append(list.str());
  out.commit();
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
  if (fs::is_symlink(fs::symlink_status(dir_, ec)))
    throw InputError(name + ": is a symbolic link (it would be replaced by a folder); name the folder itself");
  const auto st = fs::status(dir_, ec);
  if (fs::exists(st) && !fs::is_directory(st)) throw InputError(name + ": exists and is not a folder");
  if (const std::string input = input_inside(dir_); !input.empty())
    throw InputError(name + ": holds the input " + input + " (it would be deleted); choose another folder");
  if (fs::is_directory(st) && !replaceable(dir_))
    throw InputError(name + ": holds files no bmssim run wrote there (or changed since); choose a new or empty folder");
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
  // Checked again: the run may have read more inputs, and the folder may have changed since.
  if (const std::string input = input_inside(dir_); !input.empty())
    throw InputError(dir_.string() + ": holds the input " + input + " (it would be deleted); choose another folder");
  if (fs::is_symlink(fs::symlink_status(dir_, ec)) || (fs::is_directory(dir_, ec) && !replaceable(dir_)))
    throw InputError(dir_.string() + ": changed during the run (files no bmssim run wrote, or a link); not replaced");
  write_manifest(staging_);
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
