#pragma once
// Residual plots: a gnuplot script written next to the data, run in that folder; each PNG
// is drawn to NAME.tmp and renamed once gnuplot has succeeded.
#include <filesystem>
#include <string>
#include <vector>

namespace bms::diagnosis {

struct PlotOutcome {
  std::vector<std::string> pngs;  // file names inside the folder
  std::string problem;            // why there are none, if there are none
};

// residual.csv must already be in dir (columns as written by write_report).
PlotOutcome draw_residual_plots(const std::filesystem::path& dir, int cases, std::size_t samples);

}  // namespace bms::diagnosis
