#pragma once
// An output folder built whole: the files are written into a staging folder beside the
// destination (DIR.partial-PID) and the staging folder replaces DIR only in commit(), so a
// failed or interrupted run never leaves a folder that looks complete, nor mixes a new
// truth.csv with an old summary.json. Without commit() the destructor removes the staging
// folder. The checks run in the constructor, before any long work.
#include <filesystem>

namespace bms {

// The number in DIR.partial-N: this process's id, or the one its parent gave in the
// environment variable below when it runs this process for it (bmssim hil --bus uml runs
// itself again inside a guest kernel, whose process ids mean nothing outside): the parent,
// which outlives the guest, then removes that staging folder when the run did not commit it.
constexpr const char* kOutputOwnerVariable = "BMSSIM_OUTPUT_OWNER";
// Called once at start: takes the variable (and removes it from the environment).
void adopt_output_folder_owner();
long output_folder_owner();

class OutputFolder {
 public:
  // Throws InputError naming `option` when DIR cannot be an output folder: an existing file,
  // a symbolic link (dangling or not), a folder holding an input this run read
  // (input_files_read()), a non-empty folder holding anything but the files a bmssim run
  // wrote there (its .bmssim-files manifest, names and sizes), a parent that cannot be created
  // or written. commit() checks the same again before it replaces anything.
  OutputFolder(std::filesystem::path dir, const char* option = "--out");
  ~OutputFolder();
  OutputFolder(const OutputFolder&) = delete;
  OutputFolder& operator=(const OutputFolder&) = delete;

  // Where to write the files until commit().
  const std::filesystem::path& staging() const { return staging_; }
  const std::filesystem::path& destination() const { return dir_; }
  // Replaces DIR with the staging folder (an older DIR is removed). RuntimeFailure on error.
  void commit();

 private:
  std::filesystem::path dir_, staging_;
  bool committed_ = false;
};

}  // namespace bms
