#include "io/measured_profile.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cctype>

#include "io/csv_table.hpp"
#include "io/cycler_formats.hpp"
#include "io/input_error.hpp"
#include "io/text_file.hpp"

namespace bms {

namespace {

constexpr double kGapMedianFactor = 10.0;
constexpr double kGapMinimumS = 60.0;
constexpr double kGapRestShare = 0.01;
constexpr double kGapRestCurrentA = 1e-3;
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
  std::string kind;
  std::string time, current, voltage, temperature;
  bool negate_current = false;
  bool celsius = false;
  bool fahrenheit = false;
  double time_scale = 1.0, current_scale = 1.0, voltage_scale = 1.0;
};

// Lower case without spaces, underscores and dots: "Test_Time (s)" -> "testtime(s)".
std::string normalised(std::string_view s) {
  std::string out;
  for (char c : s) {
    if (c == ' ' || c == '_' || c == '.') continue;
    out.push_back(static_cast<char>(std::tolower(static_cast<unsigned char>(c))));
  }
  return out;
}

bool starts_with(const std::string& s, std::string_view p) { return s.compare(0, p.size(), p) == 0; }
// The unit written after the quantity: "current(ma)" -> "ma", "i[a]" -> "a", "voltage" -> "".
std::string unit_of(const std::string& n) {
  const auto open = n.find_first_of("[(");
  if (open == std::string::npos) return {};
  const auto close = n.find_first_of("])", open + 1);
  return n.substr(open + 1, close == std::string::npos ? std::string::npos : close - open - 1);
}
std::string quantity_of(const std::string& n) { return n.substr(0, n.find_first_of("[(")); }

enum class Quantity { other, time, current, voltage, temperature };

Quantity quantity(const std::string& column) {
  const std::string n = normalised(column), q = quantity_of(n), u = unit_of(n);
  if (q == "t" && (u == "degc" || u == "c" || u == "k" || u == "degf" || u == "f")) return Quantity::temperature;
  if (starts_with(q, "temp") || q == "tcell" || q == "celltemperature") return Quantity::temperature;
  if (q == "t" || q == "time" || q == "times" || q == "testtime" || q == "totaltime" || q == "elapsedtime" ||
      q == "ts")
    return Quantity::time;
  if (q == "i" || q == "current" || q == "currenta" || q == "cellcurrent" || q == "ia") return Quantity::current;
  if (q == "u" || q == "v" || q == "voltage" || q == "voltagev" || q == "cellvoltage" || q == "ecell" || q == "uv" ||
      q == "vcell")
    return Quantity::voltage;
  return Quantity::other;
}

// Every column naming the quantity; InputError when none does or several do.
std::string pick(const CsvTable& table, Quantity want, std::string_view what, bool required) {
  std::vector<std::string> found;
  for (const std::string& c : table.columns())
    if (quantity(c) == want) found.push_back(c);
  if (found.size() > 1)
    throw InputError(fmt::format("{}: line 1: several {} columns ({}): keep one", table.name(), what,
                                 fmt::join(found, ", ")));
  if (found.empty() && required)
    throw InputError(fmt::format("{}: line 1: no {} column (the header has: {}); name it e.g. '{}'", table.name(),
                                 what, fmt::join(table.columns(), ", "),
                                 want == Quantity::time      ? "Time [s]"
                                 : want == Quantity::current ? "Current [A]"
                                                             : "Voltage [V]"));
  return found.empty() ? std::string() : found.front();
}

double unit_scale(const CsvTable& table, const std::string& column, std::string_view base) {
  const std::string u = unit_of(normalised(column));
  if (u.empty() || u == base) return 1.0;
  if (base == "s" && u == "min") return 60.0;
  if (base == "s" && u == "h") return 3600.0;
  if ((base == "a" || base == "v") && u == std::string("m") + std::string(base)) return 1e-3;
  throw InputError(fmt::format("{}: line 1: column '{}': unit '{}' not understood", table.name(), column, u));
}

Layout by_column_names(const CsvTable& table) {
  Layout l;
  l.kind = "by column names";
  l.time = pick(table, Quantity::time, "time", true);
  l.current = pick(table, Quantity::current, "current", true);
  l.voltage = pick(table, Quantity::voltage, "voltage", true);
  l.temperature = pick(table, Quantity::temperature, "temperature", false);
  l.time_scale = unit_scale(table, l.time, "s");
  l.current_scale = unit_scale(table, l.current, "a");
  l.voltage_scale = unit_scale(table, l.voltage, "v");
  const std::string tu = l.temperature.empty() ? std::string("k") : unit_of(normalised(l.temperature));
  l.fahrenheit = tu == "degf" || tu == "f" || tu == "°f" || tu == "fahrenheit";
  l.celsius = tu.empty() || tu == "degc" || tu == "c" || tu == "°c" || tu == "celsius";
  if (tu != "k" && !l.celsius && !l.fahrenheit)
    throw InputError(fmt::format("{}: line 1: column '{}': temperature unit '{}' not understood (K, degC or degF)",
                                 table.name(), l.temperature, tu));
  l.negate_current = true;
  return l;
}

Layout layout_of(const CsvTable& table, ProfileColumns which) {
  Layout l;
  if (table.has("t_s")) {
    const bool truth = which == ProfileColumns::truth;
    l.kind = "truth.csv";
    l.time = "t_s";
    l.current = truth ? "current_a" : "current_meas_a";
    l.voltage = truth ? "voltage_v" : "voltage_meas_v";
    // What a BMS reads is the sensor's column; the truth's own temperature only drives a truth.
    if (table.has("temperature_k")) l.temperature = "temperature_k";
    if (!truth && table.has("temperature_meas_k")) l.temperature = "temperature_meas_k";
    return l;
  }
  l.time = find_column(table, {"Time[s]"});
  if (l.time.empty() || find_column(table, {"I[A]"}).empty()) return by_column_names(table);
  l.kind = "About:Energy";
  l.current = find_column(table, {"I[A]"});
  l.voltage = find_column(table, {"U[V]"});
  if (l.voltage.empty()) l.voltage = "U[V]";  // reported as missing by numbers()
  l.negate_current = true;
  l.temperature = find_column(table, {"T[degC]", "Temperature[degC]"});
  l.celsius = !l.temperature.empty();
  if (!l.celsius) l.temperature = find_column(table, {"T[K]", "Temperature[K]"});
  return l;
}

// A gap is accepted when the cell rests on both sides of it (a logger that stops recording
// during a long rest): the current is interpolated across it, and at rest that is the truth.
bool rests_across(const std::vector<double>& current_a, std::size_t i) {
  double imax = 0.0;
  for (double x : current_a) imax = std::max(imax, std::abs(x));
  const double rest_a = kGapRestShare * imax + kGapRestCurrentA;
  return std::abs(current_a[i - 1]) <= rest_a && std::abs(current_a[i]) <= rest_a;
}

void check_times(const CsvTable& table, const std::string& column, const std::vector<double>& t,
                 const std::vector<double>& current_a) {
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
    if (step > kGapMedianFactor * typical && step > kGapMinimumS && !rests_across(current_a, i)) {
      throw InputError(fmt::format(
          "{}: gap of {} s in the record after t = {} s (line {}) under current; the median time step is {} s "
          "(a gap is accepted only at rest)",
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

// The voltage's response settles the current's sign: at a step of the current the voltage
// steps the other way (positive = discharge: more discharge current, lower voltage). Steps of
// over a tenth of the largest current are weighed by |dI dV|; when four fifths of that weight
// (and at least 3 steps) say the sign read is wrong, the file is refused naming the option.
void check_sign_against_voltage(const CsvTable& table, const Layout& l, const MeasuredProfile& p, bool given) {
  double imax = 0.0;
  for (double x : p.current_a) imax = std::max(imax, std::abs(x));
  double agree = 0.0, contradict = 0.0;
  std::size_t steps = 0, against = 0, first = 0;
  for (std::size_t i = 1; i < p.current_a.size(); ++i) {
    const double di = p.current_a[i] - p.current_a[i - 1], dv = p.voltage_v[i] - p.voltage_v[i - 1];
    if (!(std::abs(di) > 0.1 * imax) || dv == 0.0) continue;
    ++steps;
    if (di * dv > 0.0) {
      contradict += std::abs(di * dv);
      if (against++ == 0) first = i;
    } else {
      agree += std::abs(di * dv);
    }
  }
  if (steps < 3 || contradict <= 4.0 * agree) return;
  throw InputError(fmt::format(
      "{}: the current read as {} contradicts the voltage: at {} steps the voltage moves with the current "
      "read as discharge (first at line {}); {} --current-sign {}",
      table.name(), l.negate_current ? "charge-positive" : "discharge-positive", fmt::format("{} of {}", against, steps), CsvTable::line_of_row(first),
      given ? "check the file or" : "give", l.negate_current ? "discharge-positive" : "charge-positive"));
}

// A cycler's export read by its layout (units, sign and step types as cycler_formats.hpp reads
// them), held to this reader's rule on gaps: the commands that read a profile drive a model with
// the measured current, which cannot be interpolated over a gap under current.
MeasuredProfile cycler_profile(const std::filesystem::path& file, CurrentSign sign) {
  CyclerFile f = parse_cycler_file(read_text_file(file), file.string(), sign);
  std::vector<double> steps(f.t_s.size() - 1);
  for (std::size_t i = 1; i < f.t_s.size(); ++i) steps[i - 1] = f.t_s[i] - f.t_s[i - 1];
  const double typical = median(steps);
  for (std::size_t i = 1; i < f.t_s.size(); ++i) {
    if (steps[i - 1] > kGapMedianFactor * typical && steps[i - 1] > kGapMinimumS && !rests_across(f.current_a, i))
      throw InputError(fmt::format(
          "{}: line {}, column '{}': gap of {} s in the record after t = {} s (line {}) under current; the median "
          "time step is {} s (a gap is accepted only at rest; `estimate` steps over it)",
          f.name, f.line[i], f.time_column, steps[i - 1], f.t_s[i - 1], f.line[i - 1], typical));
  }
  MeasuredProfile p;
  p.source = f.name;
  p.layout = std::string(cycler_layout_name(f.layout));
  p.current_negated = f.sign_note.rfind("charge-positive", 0) == 0;
  p.t_s = std::move(f.t_s);
  p.current_a = std::move(f.current_a);
  p.voltage_v = std::move(f.voltage_v);
  p.temperature_k = std::move(f.temperature_k);
  return p;
}

}  // namespace

bool parse_current_sign(std::string_view text, CurrentSign& out) {
  if (text == "discharge-positive") out = CurrentSign::discharge_positive;
  else if (text == "charge-positive") out = CurrentSign::charge_positive;
  else return false;
  return true;
}

CurrentSign current_sign_option(std::string_view text) {
  CurrentSign sign = CurrentSign::by_layout;
  if (!text.empty() && text != "by-layout" && !parse_current_sign(text, sign))
    throw InputError("--current-sign: '" + std::string(text) + "' is not discharge-positive or charge-positive");
  return sign;
}

MeasuredProfile parse_measured_profile(std::string_view text, std::string_view name,
                                       ProfileColumns which, CurrentSign sign) {
  const CsvTable table = parse_csv(text, name, {"mode"});
  Layout l = layout_of(table, which);
  if (sign != CurrentSign::by_layout) l.negate_current = sign == CurrentSign::charge_positive;

  MeasuredProfile p;
  p.source = std::string(name);
  p.layout = l.kind;
  p.current_negated = l.negate_current;
  p.t_s = table.numbers(l.time);
  p.current_a = table.numbers(l.current);
  p.voltage_v = table.numbers(l.voltage);
  for (double& t : p.t_s) t *= l.time_scale;
  for (double& i : p.current_a) i *= l.current_scale;
  for (double& v : p.voltage_v) v *= l.voltage_scale;
  if (!l.temperature.empty()) p.temperature_k = table.numbers(l.temperature);
  if (table.has("mode")) p.mode = table.strings("mode");
  if (table.rows() < 2) {
    throw InputError(fmt::format("{}: needs at least 2 data rows, has {}", name, table.rows()));
  }

  check_times(table, l.time, p.t_s, p.current_a);
  check_range(table, l.voltage, p.voltage_v, 0.0, kMaxVoltageV, "voltage", "V");
  if (l.negate_current) {
    for (double& i : p.current_a) i = -i;
  }
  check_sign_against_voltage(table, l, p, sign != CurrentSign::by_layout);
  if (!l.temperature.empty()) {
    if (l.fahrenheit) {
      check_range(table, l.temperature, p.temperature_k, kMinTemperatureC * 1.8 + 32.0, kMaxTemperatureC * 1.8 + 32.0,
                  "temperature", "degF");
      for (double& t : p.temperature_k) t = (t - 32.0) / 1.8 + kCelsiusOffsetK;
    } else if (l.celsius) {
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

MeasuredProfile read_measured_profile(const std::filesystem::path& file, ProfileColumns which, CurrentSign sign) {
  if (detect_cycler_layout_of(file).layout != CyclerLayout::none) return cycler_profile(file, sign);
  return parse_measured_profile(read_text_file(file), file.string(), which, sign);
}

}  // namespace bms
