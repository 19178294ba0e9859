#pragma once
// Writes a diagnosis to its output folder: residual.csv, residual plots (PNG, via gnuplot),
// report.md and summary.json (contract keys), each atomically; summary.json last.
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "diagnosis/diagnose.hpp"

namespace bms::diagnosis {

struct ReportContext {
  std::string command_line;  // how to reproduce, quoted in report.md
  std::string cell;          // as given on the command line
  DiagnoseSettings settings;
  nlohmann::json extra = nlohmann::json::object();  // further summary.json keys (e.g. write_cell)
};

nlohmann::json summary_json(const DiagnosisResult& r, const ReportContext& ctx);

// Returns the names of the plots written (empty, with a warning in report.md, when gnuplot
// is not installed: the numbers do not depend on it).
std::vector<std::string> write_report(const std::filesystem::path& dir, const DiagnosisResult& r,
                                      const ReportContext& ctx);

}  // namespace bms::diagnosis
