#pragma once
// Writes estimates.csv and summary.json (contract: estimate; also used by hil).
#include <filesystem>

#include <nlohmann/json.hpp>

#include "estimation/estimate_run.hpp"

namespace bms {

void write_estimates_csv(const std::filesystem::path& file, const EstimateResult& r);
nlohmann::json estimate_summary_json(const EstimateResult& r, const EstimateOptions& o);

}  // namespace bms
