#pragma once
// Draws the collected figures with gnuplot (PNG) and writes DIR/report.md: each figure beside
// the paper's statement about the same figure, and the headline table.
#include <filesystem>
#include <string>

#include "studies/study_collect.hpp"

namespace bms::study {

// Writes DIR/figures/*.gp and, when gnuplot is installed, DIR/figures/*.png. Returns the
// number of figures drawn (0 without gnuplot: the report then says how to draw them).
int draw_figures(const std::filesystem::path& out_dir, const Collected& c);

// The headline table as markdown rows (also used by docs/results/paper.md).
std::string headline_table(const nlohmann::json& summary);

void write_report(const std::filesystem::path& out_dir, const Collected& c, int drawn, const std::string& command);

}  // namespace bms::study
