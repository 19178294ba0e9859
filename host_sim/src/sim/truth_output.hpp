#pragma once
// Writes a simulation's truth.csv and summary.json (contract: simulate).
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "sim/cycler.hpp"
#include "sim/measurement.hpp"

namespace bms {

// Writes text to FILE.tmp and renames it, so a reader never sees a partial file.
void write_file_atomically(const std::filesystem::path& file, const std::string& text);

void write_truth_csv(const std::filesystem::path& file, const SimulationResult& r, const Measured& m);

nlohmann::json summary_json(const SimulationResult& r);

}  // namespace bms
