#pragma once
#include <filesystem>
#include <string>

#include "cell/cell_parameters.hpp"

namespace bms {

// Where ../shared lives: $BMS_SHARED_DIR, else the folder beside the source tree.
std::filesystem::path shared_dir();

// "paper" (built-in), "aboutenergy" (the About:Energy LFP 18650 BPX file in shared/), or a
// path to any BPX 0.1 JSON file. Throws InputError naming the cell or file.
CellParameters load_cell(const std::string& name_or_file);

}  // namespace bms
