#pragma once
// The host tools' one way to draw a plot: gnuplot run on a script through the process runner
// (io/child_process), so an interrupt reaches it like any other child, and then throws
// Interrupted once gnuplot ended.
#include <filesystem>
#include <string>
#include <vector>

namespace bms {

struct GnuplotOptions {
  std::filesystem::path working_dir;  // the script's relative paths start here; empty: ours
  std::filesystem::path log;          // gnuplot's output appended here; empty: inherited
};

// Runs `gnuplot script`: gnuplot's exit code, or kGnuplotMissing when it cannot be started
// (not installed: Debian package gnuplot-nox).
constexpr int kGnuplotMissing = -1;
int run_gnuplot(const std::filesystem::path& script, const GnuplotOptions& options = {});
// After a script that wrote each of `names` as NAME.tmp in `dir` exited with `rc`: renames them
// into place (rc 0) or removes them. Returns the names now in place; `problem` says what went
// wrong (gnuplot missing or failed, a rename failed), empty when nothing did.
std::vector<std::string> commit_plots(const std::filesystem::path& dir, const std::vector<std::string>& names, int rc,
                                      std::string& problem);

}  // namespace bms
