#include "io/gnuplot.hpp"

#include "io/child_process.hpp"
#include "io/input_error.hpp"

namespace bms {

int run_gnuplot(const std::filesystem::path& script, const GnuplotOptions& options) {
  SpawnOptions spawn;
  spawn.search_path = true;
  spawn.log = options.log;
  spawn.working_dir = options.working_dir;
  int rc = 0;
  try {
    rc = run_process({"gnuplot", script.string()}, spawn);
  } catch (const RuntimeFailure&) {
    return kGnuplotMissing;
  }
  // A plot stopped by SIGINT/SIGTERM (forwarded to gnuplot) stops the command, which removes
  // its unfinished output: never a folder that looks complete without its plots.
  throw_if_interrupted();
  // 127: the shell convention for a program the child could not execute.
  return rc == 127 ? kGnuplotMissing : rc;
}

std::vector<std::string> commit_plots(const std::filesystem::path& dir, const std::vector<std::string>& names, int rc,
                                      std::string& problem) {
  std::vector<std::string> in_place;
  problem.clear();
  for (const auto& n : names) {
    std::error_code ec;
    if (rc != 0) {
      std::filesystem::remove(dir / (n + ".tmp"), ec);
      continue;
    }
    std::filesystem::rename(dir / (n + ".tmp"), dir / n, ec);
    if (ec && problem.empty()) problem = n + ": " + ec.message();
    if (!ec) in_place.push_back(n);
  }
  if (rc == kGnuplotMissing) problem = "gnuplot is not installed (Debian package gnuplot-nox)";
  else if (rc != 0) problem = "gnuplot failed (exit status " + std::to_string(rc) + ")";
  return in_place;
}

}  // namespace bms
