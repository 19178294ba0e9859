#pragma once
// Whole-file reads for the input parsers, with the file named in every error.
#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace bms {

// The largest input file read whole (a 400-cycle truth.csv at 0.2 s is about 2 GB).
constexpr std::uintmax_t kMaxInputFileBytes = std::uintmax_t{2} << 30;

// Throws InputError "FILE: cannot read: REASON" (missing file, directory, no permission), and
// before opening it when FILE is not a regular file (a FIFO would block, /dev/zero never
// ends) or is larger than max_bytes.
std::string read_text_file(const std::filesystem::path& file, std::uintmax_t max_bytes = kMaxInputFileBytes);

// Every file read_text_file has read in this process (absolute, symbolic links resolved): an
// output folder must never replace a folder an input lives in (io/output_folder.hpp). Threads may
// read files at once; this list is read once they are done.
const std::vector<std::filesystem::path>& input_files_read();

}  // namespace bms
