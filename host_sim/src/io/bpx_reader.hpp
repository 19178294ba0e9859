#pragma once
// Battery Parameter eXchange (BPX) 0.1 JSON -> CellParameters, interpreted as PyBaMM's BPX
// reader does (see bpx_reader.cpp). Every problem is an InputError naming the file and the
// full field path, e.g. "lfp.json: missing field 'Parameterisation.Separator.Porosity'".
#include <filesystem>
#include <string_view>

#include "cell/cell_parameters.hpp"

namespace bms {

CellParameters read_bpx(const std::filesystem::path& file);
// The same from memory; `name` stands for the file in messages and CellParameters::source.
CellParameters read_bpx_text(std::string_view json, std::string_view name);

}  // namespace bms
