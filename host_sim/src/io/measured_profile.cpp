#include "io/measured_profile.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>

#include "io/csv_table.hpp"
#include "io/input_error.hpp"
#include "io/text_file.hpp"

namespace bms {

namespace {

constexpr double kGapMedianFactor = 10.0;
constexpr double kGapMinimumS = 60.0;
constexpr double kMaxVoltageV = 10.0;
// -100..200 degC: wide, but catches a Celsius column labelled as kelvin and vice versa.
constexpr double kMinTemperatureC = -100.0;
constexpr double kMaxTemperatureC = 200.0;
constexpr double kMinTemperatureK = 173.15;
constexpr double kMaxTemperatureK = 473.15;
constexpr double kCelsiusOffsetK = 273.15;
constexpr std::array<std::string_view, 5> kModes = {"rest", "cc_discharge", "cv_discharge",
                                                    "cc_charge", "cv_charge"};

// About:Energy headers come as "I[A]" or "I [A]"; compare without spaces.
std::string without_spaces(std::string_view s) {
  std::string out;
  for (char c : s) {
    if (c != ' ') out.push_back(c);
  }
  return out;
}

// The header's own spelling of the first of `names` it holds, or "" if none.
std::string find_column(const CsvTable& table, std::initializer_list<std::string_view> names) {
  for (const std::string& column : table.columns()) {
    for (std::string_view n : names) {
      if (without_spaces(column) == n) return column;
    }
  }
  return {};
}

double median(std::vector<double> v) {
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

struct Layout {
  std::string time, current, voltage, temperature;
  bool negate_current = false;
  bool celsius = false;
};

Layout layout_of(const CsvTable& table, ProfileColumns which) {
  Layout l;
  if (table.has("t_s")) {
    const bool truth = which == ProfileColumns::truth;
    l.time = "t_s";
    l.current = truth ? "current_a" : "current_meas_a";
    l.voltage = truth ? "voltage_v" : "voltage_meas_v";
    if (table.has("temperature_k")) l.temperature = "temperature_k";
    return l;
  }
  l.time = find_column(table, {"Time[s]"});
  if (l.time.empty()) {
    throw InputError(fmt::format(
        "{}: line 1: unrecognised header '{}' (expected 'Time [s],I[A],U[V]' or a truth.csv "
        "header with 't_s')",
        table.name(), fmt::join(table.columns(), ",")));
  }
  l.current = find_column(table, {"I[A]"});
  if (l.current.empty()) l.current = "I[A]";  // reported as missing by numbers()
  l.voltage = find_column(table, {"U[V]"});
  if (l.voltage.empty()) l.voltage = "U[V]";
  l.negate_current = true;
  l.temperature = find_column(table, {"T[degC]", "Temperature[degC]"});
  l.celsius = !l.temperature.empty();
  if (!l.celsius) l.temperature = find_column(table, {"T[K]", "Temperature[K]"});
  return l;
}

void check_times(const CsvTable& table, const std::string& column, const std::vector<double>& t) {
  std::vector<double> steps(t.size() - 1);
  for (std::size_t i = 1; i < t.size(); ++i) {
    steps[i - 1] = t[i] - t[i - 1];
    if (!(t[i] > t[i - 1])) {
      throw InputError(fmt::format(
          "{}: time {} s {} the previous row's {} s (time must strictly increase)",
          table.where(i, column), t[i], t[i] == t[i - 1] ? "repeats" : "goes back from", t[i - 1]));
    }
  }
  const double typical = median(steps);
  for (std::size_t i = 1; i < t.size(); ++i) {
    const double step = steps[i - 1];
    if (step > kGapMedianFactor * typical && step > kGapMinimumS) {
      throw InputError(fmt::format(
          "{}: gap of {} s in the record after t = {} s (line {}); the median time step is {} s",
          table.where(i, column), step, t[i - 1], CsvTable::line_of_row(i - 1), typical));
    }
  }
}

void check_range(const CsvTable& table, const std::string& column, const std::vector<double>& v,
                 double lo, double hi, std::string_view quantity, std::string_view unit) {
  for (std::size_t i = 0; i < v.size(); ++i) {
    if (v[i] < lo || v[i] > hi) {
      throw InputError(fmt::format("{}: {} {} {} outside {}..{} {}", table.where(i, column),
                                   quantity, v[i], unit, lo, hi, unit));
    }
  }
}

}  // namespace

MeasuredProfile parse_measured_profile(std::string_view text, std::string_view name,
                                       ProfileColumns which) {
  const CsvTable table = parse_csv(text, name, {"mode"});
  const Layout l = layout_of(table, which);

  MeasuredProfile p;
  p.source = std::string(name);
  p.t_s = table.numbers(l.time);
  p.current_a = table.numbers(l.current);
  p.voltage_v = table.numbers(l.voltage);
  if (!l.temperature.empty()) p.temperature_k = table.numbers(l.temperature);
  if (table.has("mode")) p.mode = table.strings("mode");
  if (table.rows() < 2) {
    throw InputError(fmt::format("{}: needs at least 2 data rows, has {}", name, table.rows()));
  }

  check_times(table, l.time, p.t_s);
  check_range(table, l.voltage, p.voltage_v, 0.0, kMaxVoltageV, "voltage", "V");
  if (l.negate_current) {
    for (double& i : p.current_a) i = -i;
  }
  if (!l.temperature.empty()) {
    if (l.celsius) {
      check_range(table, l.temperature, p.temperature_k, kMinTemperatureC, kMaxTemperatureC,
                  "temperature", "degC");
      for (double& t : p.temperature_k) t += kCelsiusOffsetK;
    } else {
      check_range(table, l.temperature, p.temperature_k, kMinTemperatureK, kMaxTemperatureK,
                  "temperature", "K");
    }
  }
  for (std::size_t i = 0; i < p.mode.size(); ++i) {
    if (std::find(kModes.begin(), kModes.end(), p.mode[i]) == kModes.end()) {
      throw InputError(fmt::format("{}: unknown mode '{}' (expected one of {})",
                                   table.where(i, "mode"), p.mode[i], fmt::join(kModes, ", ")));
    }
  }
  return p;
}

MeasuredProfile read_measured_profile(const std::filesystem::path& file, ProfileColumns which) {
  return parse_measured_profile(read_text_file(file), file.string(), which);
}

}  // namespace bms
