#pragma once
// Whole-file reads for the input parsers, with the file named in every error.
#include <filesystem>
#include <string>

namespace bms {

// Throws InputError "FILE: cannot read: REASON" (missing file, directory, no permission).
std::string read_text_file(const std::filesystem::path& file);

}  // namespace bms
