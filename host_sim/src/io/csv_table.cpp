#include "io/csv_table.hpp"

#include <algorithm>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <system_error>

#include "io/input_error.hpp"
#include "io/text_file.hpp"

namespace bms {

namespace {

std::string_view trim(std::string_view s) {
  const auto space = [](char c) { return c == ' ' || c == '\t'; };
  while (!s.empty() && space(s.front())) s.remove_prefix(1);
  while (!s.empty() && space(s.back())) s.remove_suffix(1);
  return s;
}

bool blank(std::string_view line) { return trim(line).empty(); }

std::vector<std::string_view> split(std::string_view line) {
  std::vector<std::string_view> cells;
  for (;;) {
    const std::size_t comma = line.find(',');
    cells.push_back(trim(line.substr(0, comma)));
    if (comma == std::string_view::npos) return cells;
    line.remove_prefix(comma + 1);
  }
}

std::string quoted(std::string_view cell) {
  constexpr std::size_t kShown = 40;
  if (cell.size() <= kShown) return fmt::format("'{}'", cell);
  return fmt::format("'{}...'", cell.substr(0, kShown));
}

// from_chars rather than strtod: independent of the C locale, and it reports how much it
// consumed, so "1.5V" or "1,5" are rejected instead of read as 1.5 or 1.
std::string parse_number(std::string_view cell, double& value) {
  if (cell.empty()) return "empty cell";
  std::string_view digits = cell;
  if (digits.size() > 1 && digits.front() == '+' && digits[1] != '-') digits.remove_prefix(1);
  const auto [end, ec] = std::from_chars(digits.data(), digits.data() + digits.size(), value);
  if (ec == std::errc::result_out_of_range) return "number out of range: " + quoted(cell);
  if (ec != std::errc() || end != digits.data() + digits.size()) {
    return "not a number: " + quoted(cell);
  }
  if (!std::isfinite(value)) return "not a finite number: " + quoted(cell);
  return {};
}

}  // namespace

bool CsvTable::has(std::string_view column) const {
  return std::find(columns_.begin(), columns_.end(), column) != columns_.end();
}

std::size_t CsvTable::index(std::string_view column) const {
  const auto it = std::find(columns_.begin(), columns_.end(), column);
  if (it == columns_.end()) {
    throw InputError(fmt::format("{}: line 1: missing column '{}' (the header has: {})", name_,
                                 column, fmt::join(columns_, ", ")));
  }
  return static_cast<std::size_t>(it - columns_.begin());
}

const std::vector<double>& CsvTable::numbers(std::string_view column) const {
  const Column& c = data_[index(column)];
  if (c.text) throw std::logic_error(fmt::format("CSV column '{}' was read as text", column));
  if (!c.error.empty()) throw InputError(c.error);
  if (!c.nan_error.empty()) throw InputError(c.nan_error);
  return c.numbers;
}

const std::vector<double>& CsvTable::numbers_or_nan(std::string_view column) const {
  const Column& c = data_[index(column)];
  if (c.text) throw std::logic_error(fmt::format("CSV column '{}' was read as text", column));
  if (!c.error.empty()) throw InputError(c.error);
  return c.numbers;
}

const std::vector<std::string>& CsvTable::strings(std::string_view column) const {
  const Column& c = data_[index(column)];
  if (!c.text) throw std::logic_error(fmt::format("CSV column '{}' was read as numbers", column));
  return c.strings;
}

std::string CsvTable::where(std::size_t row, std::string_view column) const {
  const std::size_t i = index(column);
  return fmt::format("{}: line {}, column {} ('{}')", name_, line_of_row(row), i + 1, column);
}

CsvTable parse_csv(std::string_view text, std::string_view name,
                   const std::vector<std::string>& text_columns) {
  constexpr std::string_view kBom = "\xEF\xBB\xBF";
  if (text.substr(0, kBom.size()) == kBom) text.remove_prefix(kBom.size());
  if (text.find('\0') != std::string_view::npos)
    throw InputError(fmt::format("{}: NUL bytes in the text (UTF-16 or a binary file?): save it as UTF-8 CSV", name));

  std::vector<std::string_view> lines;
  while (!text.empty()) {
    const std::size_t nl = text.find('\n');
    std::string_view line = text.substr(0, nl);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    lines.push_back(line);
    text.remove_prefix(nl == std::string_view::npos ? text.size() : nl + 1);
  }
  while (!lines.empty() && blank(lines.back())) lines.pop_back();
  if (lines.empty()) throw InputError(fmt::format("{}: empty file (expected a header line)", name));

  CsvTable t;
  t.name_ = std::string(name);
  for (std::string_view header : split(lines[0])) {
    const std::size_t column = t.columns_.size() + 1;
    if (header.empty()) {
      throw InputError(fmt::format("{}: line 1, column {}: empty column name", name, column));
    }
    if (t.has(header)) {
      throw InputError(
          fmt::format("{}: line 1, column {}: duplicate column name '{}'", name, column, header));
    }
    t.columns_.emplace_back(header);
  }

  if (t.columns_.size() == 1 && lines[0].find(';') != std::string_view::npos)
    throw InputError(fmt::format("{}: line 1: columns separated by ';' (a European CSV?): save it with ',' between "
                                 "columns and '.' as the decimal point",
                                 name));
  t.rows_ = lines.size() - 1;
  t.data_.resize(t.columns_.size());
  for (std::size_t c = 0; c < t.columns_.size(); ++c) {
    CsvTable::Column& col = t.data_[c];
    col.text =
        std::find(text_columns.begin(), text_columns.end(), t.columns_[c]) != text_columns.end();
    if (col.text) {
      col.strings.reserve(t.rows_);
    } else {
      col.numbers.reserve(t.rows_);
    }
  }

  for (std::size_t row = 0; row < t.rows_; ++row) {
    const std::size_t line = CsvTable::line_of_row(row);
    const std::string_view text_line = lines[row + 1];
    if (blank(text_line)) {
      throw InputError(fmt::format("{}: line {}: blank line inside the data", name, line));
    }
    const std::vector<std::string_view> cells = split(text_line);
    if (cells.size() != t.columns_.size()) {
      throw InputError(fmt::format("{}: line {}: {} cells, but the header has {} columns", name,
                                   line, cells.size(), t.columns_.size()));
    }
    for (std::size_t c = 0; c < cells.size(); ++c) {
      CsvTable::Column& col = t.data_[c];
      if (col.text) {
        col.strings.emplace_back(cells[c]);
        continue;
      }
      if (!col.error.empty()) continue;
      double v = 0.0;
      const std::string problem = parse_number(cells[c], v);
      const bool nan_cell = !problem.empty() && std::isnan(v);  // a 'nan' literal: parsed, not finite
      col.numbers.push_back(v);
      if (problem.empty()) continue;
      std::string& first = nan_cell ? col.nan_error : col.error;
      if (first.empty())
        first = fmt::format("{}: line {}, column {} ('{}'): {}", name, line, c + 1, t.columns_[c], problem);
      if (!nan_cell) col.numbers = {};
    }
  }
  return t;
}

CsvTable read_csv(const std::filesystem::path& file, const std::vector<std::string>& text_columns) {
  return parse_csv(read_text_file(file), file.string(), text_columns);
}

CsvWriter::CsvWriter(std::filesystem::path file, std::vector<std::string> columns)
    : file_(std::move(file)), columns_(columns.size()) {
  if (columns.empty()) throw std::invalid_argument("CsvWriter needs at least one column");
  for (const std::string& c : columns) cell(std::string_view(c));  // validates before opening
  out_ = std::make_unique<AtomicFileWriter>(file_);
  end_row();
}

CsvWriter::~CsvWriter() = default;

void CsvWriter::separator() {
  if (cells_++ > 0) buffer_.push_back(',');
}

CsvWriter& CsvWriter::cell(double v) {
  separator();
  fmt::format_to(std::back_inserter(buffer_), "{}", v);
  return *this;
}

CsvWriter& CsvWriter::cell(std::string_view text) {
  if (text.find_first_of(",\"\r\n") != std::string_view::npos) {
    throw std::invalid_argument(fmt::format("CSV cell '{}' needs quoting", text));
  }
  separator();
  buffer_.append(text);
  return *this;
}

void CsvWriter::end_row() {
  if (cells_ != columns_) {
    throw std::logic_error(
        fmt::format("{}: row with {} cells, expected {}", file_.string(), cells_, columns_));
  }
  buffer_.push_back('\n');
  cells_ = 0;
  out_->append(std::string_view(buffer_.data(), buffer_.size()));
  buffer_.clear();
}

void CsvWriter::commit() {
  if (cells_ != 0) throw std::logic_error(fmt::format("{}: unfinished row", file_.string()));
  out_->commit();
}

}  // namespace bms
