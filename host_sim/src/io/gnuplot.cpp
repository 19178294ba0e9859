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

}  // namespace bms
