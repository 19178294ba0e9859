#pragma once
// The host tools' one way to draw a plot: gnuplot run on a script through the process runner
// (io/child_process), so an interrupt reaches it like any other child, and then throws
// Interrupted once gnuplot ended.
#include <filesystem>

namespace bms {

struct GnuplotOptions {
  std::filesystem::path working_dir;  // the script's relative paths start here; empty: ours
  std::filesystem::path log;          // gnuplot's output appended here; empty: inherited
};

// Runs `gnuplot script`: gnuplot's exit code, or kGnuplotMissing when it cannot be started
// (not installed: Debian package gnuplot-nox).
constexpr int kGnuplotMissing = -1;
int run_gnuplot(const std::filesystem::path& script, const GnuplotOptions& options = {});

}  // namespace bms
