#pragma once
// Merges the case outputs under DIR/cases into the study's headline numbers (summary.json)
// and the data of the paper's figures 8-17 (DIR/figures/*.dat). Reads only files; runs nothing.
#include <filesystem>
#include <string>
#include <vector>

#include <nlohmann/json.hpp>

#include "studies/study_plan.hpp"

namespace bms::study {

// One figure: its data file (gnuplot blocks) and what to draw; drawn by study_report.
struct FigureData {
  std::string id;     // "fig08"
  std::string title;  // plot title
  std::string xlabel, ylabel;
  // One line per curve: data block index in the .dat file, column x, column y, legend.
  struct Curve {
    int block;
    int x_col, y_col;
    std::string legend;
  };
  std::vector<Curve> curves;
  std::string style = "lines";  // gnuplot "with" style
  double y_min = 0.0, y_max = 0.0;  // y range when y_min < y_max (a magnified view), else automatic
};

struct Collected {
  nlohmann::json summary;  // written as DIR/summary.json
  std::vector<FigureData> figures;
  std::vector<std::string> missing;  // cases or steps without output (reported, not fatal)
};

// Reads every DIR/cases/*/case.json and the step outputs that exist. Writes the figure data
// files into DIR/figures. Throws InputError naming the file for unreadable output.
Collected collect(const std::filesystem::path& out_dir);

}  // namespace bms::study
