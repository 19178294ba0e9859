#pragma once
// Writing a cell as BPX JSON: the edits a derived cell makes to its source file (a field by
// section and key, a number, expression or table scaled by a factor) and the file itself
// (header, checked by reading it back with the reader every --cell uses, written atomically).
// Shared by `bmssim fit` (the fitted cell) and `bmssim diagnose --write-cell` (the augmented cell).
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

namespace bms {

// Parameterisation.SECTION.KEY of a BPX document (the section is created when missing).
nlohmann::json& bpx_field(nlohmann::json& bpx, const char* section, const char* key);

// A number, an expression or a table ({"x":..,"y":..}) times f; InputError naming `where` otherwise.
void scale_bpx_value(nlohmann::json& v, double f, const std::string& where);

// A number, or a string holding just a number; InputError naming `where` otherwise.
double bpx_number(const nlohmann::json& v, const std::string& where);

// Writes `cell` to `file` (FILE.tmp, renamed when complete) with Header.Title and
// Header.Description replaced. The text is read back by read_bpx_text first: a cell the reader
// refuses is never written (RuntimeFailure naming the field).
void write_bpx_cell(const std::filesystem::path& file, nlohmann::json cell, const std::string& title,
                    const std::string& description);

}  // namespace bms
