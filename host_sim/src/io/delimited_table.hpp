#pragma once
// A text table as cycler software exports it: a header line somewhere after some metadata
// lines, cells separated by commas, tabs or semicolons, cells optionally in double quotes, a
// decimal comma in tab- or semicolon-separated files (a European locale's EC-Lab or CSV).
// Numbers, clock times and dates are parsed on request, column by column; every error names the
// file, the 1-based line and the column ("FILE: line L, column C ('NAME'): ...").
#include <cstddef>
#include <string>
#include <string_view>
#include <vector>

namespace bms {

// How a date "A/B/YYYY" is read: month first (the US) or day first (most other places). A date
// "DD.MM.YYYY" is always day first.
enum class DayOrder { month_first, day_first };

class DelimitedTable {
 public:
  // `header_line`: 0-based index of the header among the text's lines. Lines after it up to
  // the end (blank lines at the end dropped) are data rows. A trailing empty header cell (a
  // line that ends in the delimiter) is dropped, and so is the matching trailing cell of a row.
  // Only the first column may be unnamed (a row index).
  DelimitedTable(std::string text, std::string name, std::size_t header_line, char delimiter);

  const std::string& name() const { return name_; }
  const std::vector<std::string>& columns() const { return columns_; }
  std::size_t rows() const { return rows_.size(); }
  // Index of the column, or npos.
  std::size_t find(std::string_view column) const;
  bool has(std::string_view column) const { return find(column) != npos; }
  static constexpr std::size_t npos = static_cast<std::size_t>(-1);

  std::size_t line_of_row(std::size_t row) const { return header_line_ + 2 + row; }  // 1-based
  std::string where(std::size_t row, std::size_t column) const;
  std::string where_header(std::size_t column) const;

  std::string_view cell(std::size_t row, std::size_t column) const;
  // Every cell of the column as a finite number (InputError at the first that is not).
  std::vector<double> numbers(std::size_t column) const;
  // As numbers(), but a cell may also be a duration "[Nd ]H:MM:SS[.fff]" (hours may exceed 24),
  // in seconds; a plain number is multiplied by `number_scale_s` (NaN: the header gives no unit,
  // and a plain number is refused).
  std::vector<double> durations_s(std::size_t column, double number_scale_s) const;
  // Every cell as seconds since 1970-01-01 00:00 (a date read as UTC: only differences are used):
  // "YYYY-MM-DD HH:MM:SS[.fff]", "YYYY/MM/DD ...", "DD.MM.YYYY ...", "MM/DD/YYYY HH:MM:SS[.fff][ AM|PM]"
  // or "DD/MM/YYYY ...", the order told by day_order (InputError where it cannot be told).
  std::vector<double> date_times_s(std::size_t column) const;
  // The order of day and month in the column's "A/B/YYYY" dates, told by the cells: a first
  // number over 12 says day first, a second over 12 or an AM/PM clock month first. InputError
  // where cells disagree; false where none tells and the two readings give different times.
  bool day_order(std::size_t column, DayOrder& order) const;
  std::vector<std::string> strings(std::size_t column) const;

 private:
  std::string text_;
  std::string name_;
  std::size_t header_line_;
  char delimiter_;
  std::vector<std::string> columns_;
  std::vector<std::vector<std::string_view>> rows_;
};

// Splits one line at `delimiter`, honouring double quotes ("a,b" is one cell; "" inside quotes
// is a quote); cells are trimmed of spaces and the quotes removed.
std::vector<std::string> split_delimited(std::string_view line, char delimiter);

// Parses one date/time text as DelimitedTable::date_times_s does; false if it is none of those.
bool parse_date_time_s(std::string_view text, double& seconds, DayOrder order = DayOrder::month_first);
// Parses one duration "[Nd ]H:MM:SS[.fff]" or a plain number of seconds; false otherwise.
bool parse_duration_s(std::string_view text, double& seconds);

}  // namespace bms
