#include "io/delimited_table.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>

#include "io/input_error.hpp"

namespace bms {

namespace {

std::string_view trim(std::string_view s) {
  const auto space = [](char c) { return c == ' ' || c == '\t' || c == '\r'; };
  while (!s.empty() && space(s.front())) s.remove_prefix(1);
  while (!s.empty() && space(s.back())) s.remove_suffix(1);
  return s;
}

// Cells of one line as views into it (quotes removed, not unescaped).
std::vector<std::string_view> split_views(std::string_view line, char delimiter) {
  std::vector<std::string_view> cells;
  std::size_t start = 0;
  bool quoted = false;
  for (std::size_t i = 0; i <= line.size(); ++i) {
    if (i < line.size() && line[i] == '"') quoted = !quoted;
    if (i < line.size() && (quoted || line[i] != delimiter)) continue;
    std::string_view c = line.substr(start, i - start);
    c = trim(c);
    if (c.size() >= 2 && c.front() == '"' && c.back() == '"') c = c.substr(1, c.size() - 2);
    cells.push_back(c);
    start = i + 1;
  }
  return cells;
}

bool parse_plain(std::string_view cell, double& value, bool decimal_comma) {
  std::string buffer;
  if (decimal_comma && cell.find(',') != std::string_view::npos && cell.find('.') == std::string_view::npos) {
    buffer.assign(cell);
    std::replace(buffer.begin(), buffer.end(), ',', '.');
    cell = buffer;
  }
  if (cell.size() > 1 && cell.front() == '+') cell.remove_prefix(1);
  if (cell.empty()) return false;
  const auto [end, ec] = std::from_chars(cell.data(), cell.data() + cell.size(), value);
  return ec == std::errc() && end == cell.data() + cell.size() && std::isfinite(value);
}

// Days from 1970-01-01 to the given civil date (proleptic Gregorian).
long days_from_civil(long y, unsigned m, unsigned d) {
  y -= m <= 2 ? 1 : 0;
  const long era = (y >= 0 ? y : y - 399) / 400;
  const auto yoe = static_cast<unsigned>(y - era * 400);
  const unsigned doy = (153 * (m + (m > 2 ? -3 : 9)) + 2) / 5 + d - 1;
  const unsigned doe = yoe * 365 + yoe / 4 - yoe / 100 + doy;
  return era * 146097 + static_cast<long>(doe) - 719468;
}

// "HH:MM:SS[.fff]" -> seconds; false if malformed.
bool parse_clock(std::string_view s, double& seconds) {
  const auto c1 = s.find(':');
  if (c1 == std::string_view::npos) return false;
  const auto c2 = s.find(':', c1 + 1);
  double h = 0, m = 0, sec = 0;
  // Whole hours and minutes: "1.02:03:04" is a day and 2 h (read by parse_duration_s), never 1.02 h.
  if (!parse_plain(s.substr(0, c1), h, false) || h != std::floor(h)) return false;
  if (c2 == std::string_view::npos) {  // "MM:SS.f" (h:min:s with no hours is rare; accept M:S)
    if (!parse_plain(s.substr(c1 + 1), sec, false)) return false;
    seconds = h * 60.0 + sec;
    return h >= 0 && sec >= 0 && sec < 60.0;
  }
  if (!parse_plain(s.substr(c1 + 1, c2 - c1 - 1), m, false) || m != std::floor(m) ||
      !parse_plain(s.substr(c2 + 1), sec, false))
    return false;
  if (h < 0 || m < 0 || m >= 60 || sec < 0 || sec >= 61.0) return false;
  seconds = h * 3600.0 + m * 60.0 + sec;
  return true;
}

}  // namespace

std::vector<std::string> split_delimited(std::string_view line, char delimiter) {
  std::vector<std::string> out;
  for (std::string_view v : split_views(line, delimiter)) out.emplace_back(v);
  return out;
}

bool parse_duration_s(std::string_view text, double& seconds) {
  text = trim(text);
  if (parse_plain(text, seconds, false)) return true;
  double days = 0.0;
  const auto d = text.find('d');
  const auto colon = text.find(':'), dot = text.find('.');
  if (d != std::string_view::npos) {
    if (!parse_plain(trim(text.substr(0, d)), days, false) || days < 0) return false;
    text = trim(text.substr(d + 1));
  } else if (colon != std::string_view::npos && dot < colon && text.find(':', colon + 1) != std::string_view::npos) {
    // .NET's TimeSpan "D.HH:MM:SS[.fff]" (Windows cycler software past a day): hours under 24.
    double h = 0.0;
    if (!parse_plain(text.substr(0, dot), days, false) || days < 0 || days != std::floor(days) ||
        !parse_plain(text.substr(dot + 1, colon - dot - 1), h, false) || h >= 24.0)
      return false;
    text = text.substr(dot + 1);
  }
  if (!parse_clock(text, seconds)) return false;
  seconds += days * 86400.0;
  return true;
}

bool parse_date_time_s(std::string_view text, double& seconds, DayOrder order) {
  text = trim(text);
  const auto space = text.find_first_of(" T");
  if (space == std::string_view::npos) return false;
  const std::string date(text.substr(0, space));
  std::string_view clock = trim(text.substr(space + 1));
  double pm_shift = 0.0;
  bool twelve_hour = false;
  if (clock.size() > 3 && (clock.substr(clock.size() - 2) == "AM" || clock.substr(clock.size() - 2) == "PM")) {
    twelve_hour = true;
    pm_shift = clock.substr(clock.size() - 2) == "PM" ? 12.0 * 3600.0 : 0.0;
    clock = trim(clock.substr(0, clock.size() - 2));
  }
  int a = 0, b = 0, c = 0;
  char s1 = 0, s2 = 0;
  int used = 0;
  if (std::sscanf(date.c_str(), "%d%c%d%c%d%n", &a, &s1, &b, &s2, &c, &used) != 5 || s1 != s2 ||
      static_cast<std::size_t>(used) != date.size() || (s1 != '-' && s1 != '/' && s1 != '.'))
    return false;
  int y = a, m = b, d = c;
  if (a < 100) {  // MM/DD/YYYY, DD/MM/YYYY or DD.MM.YYYY
    const bool day_first = s1 == '.' || order == DayOrder::day_first;
    y = c;
    m = day_first ? b : a;
    d = day_first ? a : b;
  }
  if (m < 1 || m > 12 || d < 1 || d > 31 || y < 1900 || y > 2200) return false;
  double clock_s = 0.0;
  if (!parse_clock(clock, clock_s)) return false;
  if (twelve_hour) {
    if (clock_s >= 13.0 * 3600.0 || clock_s < 3600.0) return false;
    if (clock_s >= 12.0 * 3600.0) clock_s -= 12.0 * 3600.0;
    clock_s += pm_shift;
  }
  seconds = static_cast<double>(days_from_civil(y, static_cast<unsigned>(m), static_cast<unsigned>(d))) * 86400.0 +
            clock_s;
  return true;
}

DelimitedTable::DelimitedTable(std::string text, std::string name, std::size_t header_line, char delimiter)
    : text_(std::move(text)), name_(std::move(name)), header_line_(header_line), delimiter_(delimiter) {
  std::string_view all = text_;
  constexpr std::string_view kBom = "\xEF\xBB\xBF";
  if (all.substr(0, kBom.size()) == kBom) all.remove_prefix(kBom.size());
  std::vector<std::string_view> lines;
  while (!all.empty()) {
    const std::size_t nl = all.find('\n');
    std::string_view line = all.substr(0, nl);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    lines.push_back(line);
    all.remove_prefix(nl == std::string_view::npos ? all.size() : nl + 1);
  }
  while (!lines.empty() && trim(lines.back()).empty()) lines.pop_back();
  if (lines.size() <= header_line_)
    throw InputError(fmt::format("{}: line {}: expected the column header, the file ends before", name_,
                                 header_line_ + 1));
  for (std::string_view h : split_views(lines[header_line_], delimiter_)) columns_.emplace_back(h);
  while (!columns_.empty() && columns_.back().empty()) columns_.pop_back();
  // An empty first name is a row index (pandas' to_csv, as data sets converted from Excel come).
  for (std::size_t c = 1; c < columns_.size(); ++c)
    if (columns_[c].empty())
      throw InputError(fmt::format("{}: line {}, column {}: empty column name", name_, header_line_ + 1, c + 1));
  for (std::size_t i = header_line_ + 1; i < lines.size(); ++i) {
    std::vector<std::string_view> cells = split_views(lines[i], delimiter_);
    while (cells.size() > columns_.size() && cells.back().empty()) cells.pop_back();
    if (cells.size() != columns_.size())
      throw InputError(fmt::format("{}: line {}: {} cells, but the header (line {}) has {} columns", name_, i + 1,
                                   cells.size(), header_line_ + 1, columns_.size()));
    rows_.push_back(std::move(cells));
  }
}

std::size_t DelimitedTable::find(std::string_view column) const {
  const auto it = std::find(columns_.begin(), columns_.end(), column);
  return it == columns_.end() ? npos : static_cast<std::size_t>(it - columns_.begin());
}

std::string DelimitedTable::where(std::size_t row, std::size_t column) const {
  return fmt::format("{}: line {}, column {} ('{}')", name_, line_of_row(row), column + 1, columns_[column]);
}

std::string DelimitedTable::where_header(std::size_t column) const {
  return fmt::format("{}: line {}, column {} ('{}')", name_, header_line_ + 1, column + 1, columns_[column]);
}

std::string_view DelimitedTable::cell(std::size_t row, std::size_t column) const { return rows_[row][column]; }

namespace {
// Where a comma may be the decimal mark, a column holding both "12.5" and "1,500" has a
// thousands separator in it (1,500 read as 1.5): refused at the second kind's first cell.
struct DecimalMarks {
  std::size_t point = DelimitedTable::npos, comma = DelimitedTable::npos;
  void see(std::string_view cell, std::size_t row) {
    if (cell.find('.') != std::string_view::npos) point = std::min(point, row);
    else if (cell.find(',') != std::string_view::npos) comma = std::min(comma, row);
  }
  void check(const DelimitedTable& t, std::size_t column) const {
    if (point == DelimitedTable::npos || comma == DelimitedTable::npos) return;
    const std::size_t later = std::max(point, comma), first = std::min(point, comma);
    throw InputError(fmt::format("{}: '{}' after '{}' on line {}: a decimal point and a decimal comma in one column "
                                 "(a thousands separator?)",
                                 t.where(later, column), t.cell(later, column), t.cell(first, column),
                                 t.line_of_row(first)));
  }
};
}  // namespace

std::vector<double> DelimitedTable::numbers(std::size_t column) const {
  std::vector<double> out(rows_.size());
  const bool decimal_comma = delimiter_ != ',';
  DecimalMarks marks;
  for (std::size_t r = 0; r < rows_.size(); ++r) {
    if (!parse_plain(rows_[r][column], out[r], decimal_comma))
      throw InputError(fmt::format("{}: not a finite number: '{}'", where(r, column), rows_[r][column]));
    if (decimal_comma) marks.see(rows_[r][column], r);
  }
  marks.check(*this, column);
  return out;
}

std::vector<double> DelimitedTable::durations_s(std::size_t column, double number_scale_s) const {
  std::vector<double> out(rows_.size());
  const bool decimal_comma = delimiter_ != ',';
  DecimalMarks marks;
  for (std::size_t r = 0; r < rows_.size(); ++r) {
    const std::string_view c = rows_[r][column];
    if (parse_plain(c, out[r], decimal_comma)) {
      if (decimal_comma) marks.see(c, r);
      if (std::isnan(number_scale_s))
        throw InputError(fmt::format("{}: a number of no stated unit: '{}' (name the unit in the header, e.g. "
                                     "'Time (s)')", where(r, column), c));
      out[r] *= number_scale_s;
    } else if (!parse_duration_s(c, out[r])) {
      throw InputError(fmt::format("{}: not a time (a number, or [Nd ]H:MM:SS[.fff]): '{}'", where(r, column), c));
    }
  }
  marks.check(*this, column);
  return out;
}

bool DelimitedTable::day_order(std::size_t column, DayOrder& order) const {
  std::size_t day_first = npos, month_first = npos, first = npos;
  bool differ = false;
  int a0 = 0, b0 = 0;
  for (std::size_t r = 0; r < rows_.size(); ++r) {
    const std::string_view cell = trim(rows_[r][column]);
    int a = 0, b = 0, y = 0;
    char s1 = 0, s2 = 0;
    const std::string date(cell.substr(0, cell.find_first_of(" T")));
    if (std::sscanf(date.c_str(), "%d%c%d%c%d", &a, &s1, &b, &s2, &y) != 5 || s1 != '/' || s2 != '/' || a >= 100)
      continue;
    const std::string_view ampm = cell.size() > 2 ? cell.substr(cell.size() - 2) : std::string_view();
    if (a > 12 && day_first == npos) day_first = r;
    if ((b > 12 || ampm == "AM" || ampm == "PM") && month_first == npos) month_first = r;
    if (first == npos) {
      first = r;
      a0 = a;
      b0 = b;
    } else if (a != a0 || b != b0) {
      differ = true;
    }
  }
  if (day_first != npos && month_first != npos)
    throw InputError(fmt::format("{}: a date with the {} first, but line {} has the {} first",
                                 where(std::max(day_first, month_first), column),
                                 day_first > month_first ? "day" : "month",
                                 line_of_row(std::min(day_first, month_first)),
                                 day_first > month_first ? "month" : "day"));
  order = day_first != npos ? DayOrder::day_first : DayOrder::month_first;
  return day_first != npos || month_first != npos || !differ;
}

std::vector<double> DelimitedTable::date_times_s(std::size_t column) const {
  DayOrder order = DayOrder::month_first;
  if (!day_order(column, order))
    throw InputError(fmt::format("{}: dates A/B/YYYY where no day is over 12: day/month or month/day cannot be told "
                                 "(write them as YYYY-MM-DD)",
                                 where(0, column)));
  std::vector<double> out(rows_.size());
  for (std::size_t r = 0; r < rows_.size(); ++r)
    if (!parse_date_time_s(rows_[r][column], out[r], order))
      throw InputError(fmt::format("{}: not a date and time (YYYY-MM-DD HH:MM:SS, DD.MM.YYYY or {} HH:MM:SS): '{}'",
                                   where(r, column), order == DayOrder::day_first ? "DD/MM/YYYY" : "MM/DD/YYYY",
                                   rows_[r][column]));
  return out;
}

std::vector<std::string> DelimitedTable::strings(std::size_t column) const {
  std::vector<std::string> out;
  out.reserve(rows_.size());
  for (const auto& row : rows_) out.emplace_back(row[column]);
  return out;
}

}  // namespace bms
