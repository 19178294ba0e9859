#include "hil/staged_output.hpp"

#include <system_error>
#include <utility>

#include "io/input_error.hpp"

namespace bms::hil {

namespace fs = std::filesystem;

StagedOutput::StagedOutput(fs::path dir) : dir_(std::move(dir)) {
  std::error_code ec;
  if (fs::exists(dir_, ec) && !fs::is_directory(dir_, ec))
    throw InputError("--out " + dir_.string() + ": exists and is not a directory");
  staging_ = dir_;
  staging_ += ".partial";
  fs::remove_all(staging_, ec);
  fs::create_directories(staging_, ec);
  if (ec) throw RuntimeFailure("cannot create " + staging_.string() + ": " + ec.message());
}

StagedOutput::~StagedOutput() {
  std::error_code ec;
  if (!committed_) fs::remove_all(staging_, ec);
}

void StagedOutput::commit(const std::string& last) {
  std::error_code ec;
  fs::create_directories(dir_, ec);
  if (ec) throw RuntimeFailure("cannot create " + dir_.string() + ": " + ec.message());
  std::vector<fs::path> files;
  for (const auto& e : fs::directory_iterator(staging_)) {
    if (e.path().filename() != last) files.push_back(e.path());
  }
  files.push_back(staging_ / last);
  for (const auto& f : files) {
    fs::rename(f, dir_ / f.filename(), ec);
    if (ec) throw RuntimeFailure("cannot move " + f.string() + " into " + dir_.string() + ": " + ec.message());
  }
  fs::remove_all(staging_, ec);
  committed_ = true;
}

}  // namespace bms::hil
