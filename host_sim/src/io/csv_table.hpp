#pragma once
// Comma-separated tables with a header line: numeric columns parsed as doubles, named text
// columns (e.g. `mode`) kept as strings. Errors name the file, the 1-based line and column.
#include <fmt/format.h>

#include <memory>

#include "io/atomic_file.hpp"

#include <cstdio>
#include <filesystem>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

namespace bms {

class CsvTable {
 public:
  const std::string& name() const { return name_; }
  const std::vector<std::string>& columns() const { return columns_; }
  std::size_t rows() const { return rows_; }
  bool has(std::string_view column) const;

  // A bad cell (empty, not a number, not finite) is reported only when its column is asked
  // for, so unused columns may hold anything. Throws InputError naming the first bad cell,
  // or the header line if the column is missing.
  const std::vector<double>& numbers(std::string_view column) const;
  // The same, with 'nan' cells read as NaN: for a column whose value may be undefined (a
  // truth's capacity where it has none); any other bad cell still throws.
  const std::vector<double>& numbers_or_nan(std::string_view column) const;
  // Only for columns declared as text when parsing; missing column -> InputError.
  const std::vector<std::string>& strings(std::string_view column) const;

  static std::size_t line_of_row(std::size_t row) { return row + 2; }  // header is line 1
  // "FILE: line L, column C ('NAME')", the prefix of a caller's message about one cell.
  std::string where(std::size_t row, std::string_view column) const;

 private:
  friend CsvTable parse_csv(std::string_view, std::string_view, const std::vector<std::string>&);
  struct Column {
    bool text = false;
    std::vector<double> numbers;
    std::vector<std::string> strings;
    std::string error;      // first bad numeric cell other than 'nan', empty if none
    std::string nan_error;  // first 'nan' cell (kept as NaN), empty if none
  };
  std::size_t index(std::string_view column) const;

  std::string name_;
  std::vector<std::string> columns_;
  std::vector<Column> data_;
  std::size_t rows_ = 0;
};

// `name` prefixes every error. Accepts a UTF-8 byte-order mark, CRLF line ends and blank
// lines at the end; cells are trimmed of spaces; quoting is not supported.
CsvTable parse_csv(std::string_view text, std::string_view name,
                   const std::vector<std::string>& text_columns = {});
CsvTable read_csv(const std::filesystem::path& file,
                  const std::vector<std::string>& text_columns = {});

// Writes FILE.tmp and renames it to FILE only in commit(), so an interrupted run never leaves
// a complete-looking FILE; without commit() the destructor deletes FILE.tmp.
// Doubles are written in the shortest form that reads back to the same value.
class CsvWriter {
 public:
  CsvWriter(std::filesystem::path file, std::vector<std::string> columns);
  ~CsvWriter();
  CsvWriter(const CsvWriter&) = delete;
  CsvWriter& operator=(const CsvWriter&) = delete;

  CsvWriter& cell(double v);
  CsvWriter& cell(std::string_view text);  // must not hold ',', '"' or line breaks
  CsvWriter& cell(const char* text) { return cell(std::string_view(text)); }
  template <class Int, std::enable_if_t<std::is_integral_v<Int>, int> = 0>
  CsvWriter& cell(Int v) {
    separator();
    fmt::format_to(std::back_inserter(buffer_), "{}", v);
    return *this;
  }
  void end_row();  // throws std::logic_error unless the row has one cell per column
  void commit();

  const std::filesystem::path& path() const { return file_; }

 private:
  void separator();

  std::filesystem::path file_;
  std::size_t columns_;
  std::size_t cells_ = 0;
  fmt::memory_buffer buffer_;  // the current row
  std::unique_ptr<AtomicFileWriter> out_;
};

}  // namespace bms
