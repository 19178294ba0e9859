#pragma once
#include <filesystem>
#include <string>

#include "cell/cell_parameters.hpp"

namespace bms {

// Where ../shared lives: $BMS_SHARED_DIR, else the folder beside the source tree.
std::filesystem::path shared_dir();

// The project's template BPX file for "lco" or "nmc" (host_sim/cells/NAME.bpx.json).
std::filesystem::path cell_template_file(const std::string& name);

// "paper" (built-in), "aboutenergy" (the About:Energy LFP 18650 BPX file in shared/), "lco" and
// "nmc" (the project's LCO/graphite and NMC/graphite templates), or a path to any BPX 0.1 JSON
// file. Throws InputError naming the cell or file.
CellParameters load_cell(const std::string& name_or_file);

}  // namespace bms
