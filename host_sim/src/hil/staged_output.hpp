#pragma once
// An output folder built under a temporary name: `bmssim hil` writes every file into
// DIR.partial and moves them into DIR only when the run succeeded (summary.json last, so a
// DIR with a summary.json is complete). A failed run (an exception, exit 1 or 2) removes
// DIR.partial and leaves DIR as it was: no truth.csv of a run that failed beside an older
// summary.json. A run killed with SIGKILL leaves DIR.partial, which no reader takes for an
// output.
#include <filesystem>
#include <string>
#include <vector>

namespace bms::hil {

class StagedOutput {
 public:
  // Throws InputError when DIR exists and is not a directory (before any work).
  explicit StagedOutput(std::filesystem::path dir);
  ~StagedOutput();
  StagedOutput(const StagedOutput&) = delete;
  StagedOutput& operator=(const StagedOutput&) = delete;

  // Where to write `name` while the run is going.
  std::filesystem::path path(const std::string& name) const { return staging_ / name; }
  // Moves the files into DIR, `last` after all others; then removes the staging folder.
  void commit(const std::string& last);

 private:
  std::filesystem::path dir_, staging_;
  bool committed_ = false;
};

}  // namespace bms::hil
