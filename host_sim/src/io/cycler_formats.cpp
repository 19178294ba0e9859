#include "io/cycler_formats.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <fstream>
#include <map>

#include "io/delimited_table.hpp"
#include "io/input_error.hpp"

namespace bms {

namespace {

constexpr double kCelsiusOffsetK = 273.15;
// The sign check: rows whose |I| is above this share of the largest |I| are under current.
constexpr double kUnderCurrentShare = 0.05;
// Refused when the voltage moves against the current's direction this many times more often
// than with it (and at least kSignEvidence times).
constexpr double kSignContradiction = 3.0;
constexpr std::size_t kSignEvidence = 10;

// Lower case without spaces, underscores, dashes and dots: "Test_Time (s)" -> "testtime(s)".
std::string normalised(std::string_view s) {
  std::string out;
  for (unsigned char c : s) {
    if (c == ' ' || c == '_' || c == '-' || c == '.') continue;
    out.push_back(static_cast<char>(std::tolower(c)));
  }
  return out;
}

// "testtime(s)" -> {"testtime", "s"}; "time/s" -> {"time", "s"}; "<i>/ma" -> {"<i>", "ma"}.
struct NameParts {
  std::string quantity, unit;
};
NameParts parts_of(std::string_view column) {
  const std::string n = normalised(column);
  const auto open = n.find_first_of("([");
  if (open != std::string::npos) {
    const auto close = n.find_first_of(")]", open + 1);
    return {n.substr(0, open), n.substr(open + 1, close == std::string::npos ? std::string::npos : close - open - 1)};
  }
  const auto slash = n.find('/');
  if (slash != std::string::npos && slash > 0) return {n.substr(0, slash), n.substr(slash + 1)};
  return {n, ""};
}

// The first column whose quantity is one of `names` (in the order of `names`); npos if none.
std::size_t column_named(const DelimitedTable& t, std::initializer_list<std::string_view> names) {
  for (std::string_view want : names)
    for (std::size_t c = 0; c < t.columns().size(); ++c)
      if (parts_of(t.columns()[c]).quantity == want) return c;
  return DelimitedTable::npos;
}

std::size_t require(const DelimitedTable& t, std::size_t c, std::string_view what, std::string_view layout,
                    std::string_view example) {
  if (c != DelimitedTable::npos) return c;
  throw InputError(fmt::format("{}: line {}: {} layout without a {} column (e.g. '{}'; the header has: {})", t.name(),
                               t.line_of_row(0) - 1, layout, what, example, fmt::join(t.columns(), ", ")));
}

double scale_from(const DelimitedTable& t, std::size_t c, const std::string& unit,
                  std::initializer_list<std::pair<std::string_view, double>> known, std::string_view what) {
  for (const auto& [u, s] : known)
    if (unit == u) return s;
  throw InputError(fmt::format("{}: {} unit '{}' not understood (expected one of: {})", t.where_header(c), what,
                               unit.empty() ? std::string("(none)") : unit,
                               fmt::join([&] {
                                 std::vector<std::string> v;
                                 for (const auto& k : known) v.emplace_back(k.first.empty() ? "(none)" : k.first);
                                 return v;
                               }(),
                                         ", ")));
}

// A column named for its unit alone ("Amps", "Volts") has that unit.
std::string unit_or_name(const DelimitedTable& t, std::size_t c) {
  const NameParts p = parts_of(t.columns()[c]);
  return p.unit.empty() ? p.quantity : p.unit;
}

double current_scale(const DelimitedTable& t, std::size_t c, std::string unit) {
  return scale_from(t, c, unit, {{"a", 1.0}, {"amps", 1.0}, {"amp", 1.0}, {"ma", 1e-3}, {"µa", 1e-6}, {"ua", 1e-6}},
                    "current");
}
double voltage_scale(const DelimitedTable& t, std::size_t c, std::string unit) {
  return scale_from(t, c, unit, {{"v", 1.0}, {"volts", 1.0}, {"volt", 1.0}, {"mv", 1e-3}}, "voltage");
}
double time_scale(const DelimitedTable& t, std::size_t c, std::string unit) {
  return scale_from(t, c, unit,
                    {{"s", 1.0}, {"sec", 1.0}, {"secs", 1.0}, {"min", 60.0}, {"h", 3600.0}, {"hr", 3600.0},
                     {"ms", 1e-3}, {"h:min:sms", 1.0}, {"h:min:s", 1.0}, {"hh:mm:ss", 1.0}, {"", std::nan("")}},
                    "time");
}

// Kelvin values from a temperature column: the unit from the header, or (none given) from the
// values' range when only one reading is possible (-100..150 degC vs 173..473 K).
std::vector<double> temperature_k(const DelimitedTable& t, std::size_t c) {
  std::vector<double> v = t.numbers(c);
  std::string unit = parts_of(t.columns()[c]).unit;
  // "\xb0c": the degree sign of a Latin-1 file (EC-Lab and Arbin write Windows code pages).
  for (const char* degc : {"c", "degc", "°c", "\xb0" "c", "\xe2\x84\x83", "oc", "deg c"})
    if (unit == degc) unit = "c";
  if (unit.empty()) {
    const auto [lo, hi] = std::minmax_element(v.begin(), v.end());
    if (!v.empty() && *lo >= -100.0 && *hi <= 150.0) unit = "c";
    else if (!v.empty() && *lo >= 173.0 && *hi <= 473.0) unit = "k";
    else
      throw InputError(fmt::format("{}: temperature without a unit, and its values ({}..{}) do not tell degC from K",
                                   t.where_header(c), v.empty() ? 0.0 : *lo, v.empty() ? 0.0 : *hi));
  }
  if (unit != "c" && unit != "k")
    throw InputError(fmt::format("{}: temperature unit '{}' not understood (degC or K)", t.where_header(c), unit));
  const double lo = unit == "c" ? -100.0 : 173.15, hi = unit == "c" ? 200.0 : 473.15;
  for (std::size_t r = 0; r < v.size(); ++r) {
    if (v[r] < lo || v[r] > hi)
      throw InputError(fmt::format("{}: temperature {} outside {}..{} {}", t.where(r, c), v[r], lo, hi,
                                   unit == "c" ? "degC" : "K"));
    if (unit == "c") v[r] += kCelsiusOffsetK;
  }
  return v;
}

std::vector<int> integers(const DelimitedTable& t, std::size_t c) {
  std::vector<int> out(t.rows(), 0);
  if (c == DelimitedTable::npos) return out;
  const std::vector<double> v = t.numbers(c);
  for (std::size_t r = 0; r < v.size(); ++r) {
    if (v[r] != std::floor(v[r]) || std::abs(v[r]) > 1e9)
      throw InputError(fmt::format("{}: an index must be a whole number, not {}", t.where(r, c), v[r]));
    out[r] = static_cast<int>(v[r]);
  }
  return out;
}

// Step direction per row: +1 charge, -1 discharge, 0 rest or other.
enum : int { kRest = 0, kCharge = 1, kDischarge = -1 };
int kind_of_name(std::string_view name) {
  const std::string n = normalised(name);
  if (n.find("dchg") != std::string::npos || n.find("discharge") != std::string::npos || n == "d") return kDischarge;
  if (n.find("chg") != std::string::npos || n.find("charge") != std::string::npos || n == "c") return kCharge;
  return kRest;
}

// What the read rows hold before the sign is settled.
struct RawColumns {
  std::vector<double> t_s, current_a, voltage_v, temperature_k, epoch_s;
  std::vector<double> step_time_s;  // time since the cycler's step began; empty when not logged
  std::vector<int> cycle, step, kind;  // kind empty when the file has no step type
  std::size_t time_col = 0, current_col = 0;
  std::size_t kind_col = DelimitedTable::npos;  // the step type's column
  double start_epoch_s = std::nan("");
  std::string no_start_why;  // why a file with dates has no start, else empty
  bool charge_positive = true;  // the layout's convention when no step type decides
  bool unsigned_possible = false;  // the layout may log |I| with the direction in the step type
};

std::string row_where(const DelimitedTable& t, std::size_t r, std::size_t c) { return t.where(r, c); }

// Settles the current's sign (to positive = discharge) and says how. A step type, where the file
// has one, decides whether the column is signed or a magnitude and which way; --current-sign
// overrides the layout's convention; the voltage's response must not contradict the result.
std::string settle_sign(const DelimitedTable& t, RawColumns& raw, CurrentSign sign) {
  double imax = 0.0;
  for (double i : raw.current_a) imax = std::max(imax, std::abs(i));
  const double under = kUnderCurrentShare * imax;
  std::string how;
  bool negate = raw.charge_positive;
  bool magnitude = false;
  if (!raw.kind.empty()) {
    std::size_t ch_pos = 0, ch_neg = 0, dis_pos = 0, dis_neg = 0, any_neg = 0;
    for (std::size_t r = 0; r < raw.current_a.size(); ++r) {
      const double i = raw.current_a[r];
      if (i < -under) ++any_neg;
      if (std::abs(i) <= under) continue;
      if (raw.kind[r] == kCharge) (i > 0 ? ch_pos : ch_neg)++;
      if (raw.kind[r] == kDischarge) (i > 0 ? dis_pos : dis_neg)++;
    }
    if (any_neg == 0 && raw.unsigned_possible && dis_pos > 0) {
      magnitude = true;
      how = "logged as a magnitude, its direction from the step type";
      // A magnitude in a step of no direction (Maccor's O, a Neware pulse) has no sign to give.
      for (std::size_t r = 0; r < raw.current_a.size(); ++r)
        if (raw.kind[r] == kRest && raw.current_a[r] > under)
          throw InputError(fmt::format("{}: current {} A logged as a magnitude in a step of no direction ('{}' in "
                                       "column {}): charge or discharge cannot be told",
                                       row_where(t, r, raw.current_col), raw.current_a[r],
                                       t.cell(r, raw.kind_col), raw.kind_col + 1));
    } else if (dis_pos + ch_neg > 0 && dis_neg + ch_pos > 0) {
      const bool discharge_positive_majority = dis_pos + ch_neg > dis_neg + ch_pos;
      for (std::size_t r = 0; r < raw.current_a.size(); ++r) {
        const double i = raw.current_a[r];
        if (std::abs(i) <= under || raw.kind[r] == kRest) continue;
        const bool dis_positive_here = (raw.kind[r] == kDischarge) == (i > 0);
        if (dis_positive_here != discharge_positive_majority)
          throw InputError(fmt::format("{}: current {} A in a {} step, against the sign of the file's other steps",
                                       row_where(t, r, raw.current_col), i,
                                       raw.kind[r] == kCharge ? "charge" : "discharge"));
      }
      negate = !discharge_positive_majority;
      how = fmt::format("{} (from the step types)", negate ? "charge-positive" : "discharge-positive");
    } else if (dis_pos + ch_neg > 0 || dis_neg + ch_pos > 0) {
      negate = dis_neg + ch_pos > 0;
      how = fmt::format("{} (from the step types)", negate ? "charge-positive" : "discharge-positive");
    }
  }
  if (sign != CurrentSign::by_layout) {
    const bool given = sign == CurrentSign::charge_positive;
    if (magnitude) {
      how += " (--current-sign not used)";
    } else if (!how.empty() && given != negate) {
      // The step types said the other way: the first row under current is read against its step.
      std::size_t r = 0;
      while (raw.kind[r] == kRest || std::abs(raw.current_a[r]) <= under) ++r;
      throw InputError(fmt::format("{}: --current-sign {} contradicts the step type ('{}' in column {}, current {})",
                                   row_where(t, r, raw.current_col), given ? "charge-positive" : "discharge-positive",
                                   t.cell(r, raw.kind_col), raw.kind_col + 1, t.cell(r, raw.current_col)));
    } else {
      negate = given;
      how = fmt::format("{} (--current-sign)", negate ? "charge-positive" : "discharge-positive");
    }
  }
  if (how.empty()) how = fmt::format("{} (the layout's convention)", negate ? "charge-positive" : "discharge-positive");
  for (std::size_t r = 0; r < raw.current_a.size(); ++r) {
    double& i = raw.current_a[r];
    if (magnitude) i = raw.kind[r] == kDischarge ? std::abs(i) : raw.kind[r] == kCharge ? -std::abs(i) : i;
    else if (negate) i = -i;
  }
  return how;
}

// Under charge (I < 0) the voltage rises, under discharge it falls: count how often it moves
// each way between consecutive samples of one direction, and refuse a sign it contradicts.
void check_sign_against_voltage(const DelimitedTable& t, const RawColumns& raw, const std::string& how) {
  double imax = 0.0;
  for (double i : raw.current_a) imax = std::max(imax, std::abs(i));
  const double under = kUnderCurrentShare * imax;
  std::size_t with = 0, against = 0, first_against = 0;
  for (std::size_t r = 1; r < raw.current_a.size(); ++r) {
    const double i0 = raw.current_a[r - 1], i1 = raw.current_a[r];
    if (std::abs(i0) <= under || std::abs(i1) <= under || (i0 > 0) != (i1 > 0)) continue;
    const double dv = raw.voltage_v[r] - raw.voltage_v[r - 1];
    if (dv == 0.0) continue;
    if ((dv < 0) == (i1 > 0)) ++with;
    else if (against++ == 0) first_against = r;
  }
  if (against >= kSignEvidence && static_cast<double>(against) > kSignContradiction * static_cast<double>(with))
    throw InputError(fmt::format(
        "{}: the current's sign, read as {}, contradicts the voltage: under it the voltage moves the wrong way in "
        "{} of {} steps (charge must raise it); give --current-sign",
        row_where(t, first_against, raw.current_col), how, against, against + with));
}

void check_time(const DelimitedTable& t, const RawColumns& raw) {
  for (std::size_t r = 1; r < raw.t_s.size(); ++r)
    if (!(raw.t_s[r] > raw.t_s[r - 1]))
      throw InputError(fmt::format("{}: time {} s {} the previous row's {} s (time must strictly increase)",
                                   row_where(t, r, raw.time_col), raw.t_s[r],
                                   raw.t_s[r] == raw.t_s[r - 1] ? "repeats" : "goes back from", raw.t_s[r - 1]));
}

void check_voltage(const DelimitedTable& t, const std::vector<double>& v, std::size_t c) {
  for (std::size_t r = 0; r < v.size(); ++r)
    if (v[r] < 0.0 || v[r] > 10.0)
      throw InputError(fmt::format("{}: voltage {} V outside 0..10 V (is the unit right?)", t.where(r, c), v[r]));
}

// Time, current and voltage columns at known positions with their units from the header.
void read_core(const DelimitedTable& t, RawColumns& raw, std::size_t time_c, std::size_t cur_c, std::size_t volt_c) {
  raw.time_col = time_c;
  raw.current_col = cur_c;
  const NameParts tp = parts_of(t.columns()[time_c]);
  raw.t_s = t.durations_s(time_c, time_scale(t, time_c, tp.unit));
  const double is = current_scale(t, cur_c, unit_or_name(t, cur_c));
  raw.current_a = t.numbers(cur_c);
  for (double& i : raw.current_a) i *= is;
  const double vs = voltage_scale(t, volt_c, unit_or_name(t, volt_c));
  raw.voltage_v = t.numbers(volt_c);
  for (double& v : raw.voltage_v) v *= vs;
  check_voltage(t, raw.voltage_v, volt_c);
}

std::size_t temperature_column(const DelimitedTable& t) {
  for (std::size_t c = 0; c < t.columns().size(); ++c) {
    const std::string q = parts_of(t.columns()[c]).quantity;
    if (q.rfind("temp", 0) == 0 || q.rfind("auxtemp", 0) == 0 || q == "t1" || q == "celltemperature") return c;
  }
  return DelimitedTable::npos;
}

void read_optional(const DelimitedTable& t, RawColumns& raw, std::size_t cycle_c, std::size_t step_c) {
  raw.cycle = integers(t, cycle_c);
  raw.step = integers(t, step_c);
  const std::size_t st = column_named(t, {"steptime"});
  if (st != DelimitedTable::npos) raw.step_time_s = t.durations_s(st, time_scale(t, st, parts_of(t.columns()[st]).unit));
  const std::size_t tc = temperature_column(t);
  if (tc != DelimitedTable::npos) raw.temperature_k = temperature_k(t, tc);
}

// The absolute start: the first row's date/time, less the time column's first value.
void start_from_dates(const DelimitedTable& t, RawColumns& raw, std::size_t date_c) {
  if (date_c == DelimitedTable::npos || t.rows() == 0) return;
  DayOrder order = DayOrder::month_first;
  if (!t.day_order(date_c, order)) {
    // Only the order among several files needs the start: refused there (read_cycler_record).
    raw.no_start_why = fmt::format("its dates in column {} do not tell day/month from month/day", date_c + 1);
    return;
  }
  double s = 0.0;
  if (!parse_date_time_s(t.cell(0, date_c), s, order))
    throw InputError(fmt::format("{}: not a date and time: '{}'", t.where(0, date_c), t.cell(0, date_c)));
  raw.start_epoch_s = s - raw.t_s.front();
}

RawColumns read_arbin(const DelimitedTable& t) {
  RawColumns raw;
  const char* L = "Arbin";
  read_core(t, raw, require(t, column_named(t, {"testtime"}), "time", L, "Test_Time(s)"),
            require(t, column_named(t, {"current"}), "current", L, "Current(A)"),
            require(t, column_named(t, {"voltage"}), "voltage", L, "Voltage(V)"));
  read_optional(t, raw, column_named(t, {"cycleindex", "cycle"}), column_named(t, {"stepindex", "step"}));
  start_from_dates(t, raw, column_named(t, {"datetime"}));
  raw.charge_positive = true;  // Arbin: positive current charges
  return raw;
}

RawColumns read_maccor(const DelimitedTable& t) {
  RawColumns raw;
  const char* L = "Maccor";
  read_core(t, raw, require(t, column_named(t, {"test", "testtime"}), "time", L, "Test (Sec)"),
            require(t, column_named(t, {"amps", "current"}), "current", L, "Amps"),
            require(t, column_named(t, {"volts", "voltage"}), "voltage", L, "Volts"));
  read_optional(t, raw, column_named(t, {"cyc#", "cycle", "cyclep"}), column_named(t, {"step"}));
  const std::size_t state = require(t, column_named(t, {"state", "md"}), "state (C/D/R)", L, "State");
  raw.kind_col = state;
  raw.kind.resize(t.rows());
  for (std::size_t r = 0; r < t.rows(); ++r) raw.kind[r] = kind_of_name(t.cell(r, state));
  raw.unsigned_possible = true;
  start_from_dates(t, raw, column_named(t, {"dpttime"}));
  return raw;
}

RawColumns read_neware(const DelimitedTable& t) {
  RawColumns raw;
  const char* L = "Neware";
  std::size_t time_c = column_named(t, {"totaltime", "testtime", "runtime"});
  const std::size_t date_c = column_named(t, {"realtime", "date", "absolutetime", "systemtime"});
  const bool absolute = time_c == DelimitedTable::npos && date_c != DelimitedTable::npos;
  if (absolute) time_c = date_c;
  const std::size_t cur_c = require(t, column_named(t, {"current"}), "current", L, "Current(mA)");
  const std::size_t volt_c = require(t, column_named(t, {"voltage"}), "voltage", L, "Voltage(V)");
  if (absolute) {
    raw.time_col = time_c;
    raw.current_col = cur_c;
    raw.epoch_s = t.date_times_s(time_c);
    raw.start_epoch_s = raw.epoch_s.front();
    for (double e : raw.epoch_s) raw.t_s.push_back(e - raw.start_epoch_s);
    raw.current_a = t.numbers(cur_c);
    const double is = current_scale(t, cur_c, unit_or_name(t, cur_c));
    for (double& i : raw.current_a) i *= is;
    raw.voltage_v = t.numbers(volt_c);
    const double vs = voltage_scale(t, volt_c, unit_or_name(t, volt_c));
    for (double& v : raw.voltage_v) v *= vs;
    check_voltage(t, raw.voltage_v, volt_c);
  } else {
    read_core(t, raw, require(t, time_c, "time", L, "Total Time"), cur_c, volt_c);
    start_from_dates(t, raw, date_c);
  }
  read_optional(t, raw, column_named(t, {"cycleid", "cycleindex", "cycle"}),
                column_named(t, {"stepid", "stepindex", "step"}));
  const std::size_t kind_c = column_named(t, {"stepname", "steptype", "status"});
  if (kind_c != DelimitedTable::npos) {
    raw.kind_col = kind_c;
    raw.kind.resize(t.rows());
    for (std::size_t r = 0; r < t.rows(); ++r) raw.kind[r] = kind_of_name(t.cell(r, kind_c));
  }
  raw.charge_positive = true;  // Neware logs discharge negative
  raw.unsigned_possible = true;
  return raw;
}

RawColumns read_biologic(const DelimitedTable& t, double start_epoch_s) {
  RawColumns raw;
  const char* L = "BioLogic";
  read_core(t, raw, require(t, column_named(t, {"time"}), "time", L, "time/s"),
            require(t, column_named(t, {"i", "<i>"}), "current", L, "I/mA"),
            require(t, column_named(t, {"ecell", "ewe", "<ewe>", "<ecell>"}), "voltage", L, "Ecell/V"));
  read_optional(t, raw, column_named(t, {"cyclenumber"}), column_named(t, {"ns"}));
  const std::size_t ox = column_named(t, {"ox/red", "ox"});
  if (ox != DelimitedTable::npos) {
    raw.kind_col = ox;
    raw.kind.resize(t.rows());
    for (std::size_t r = 0; r < t.rows(); ++r) raw.kind[r] = t.cell(r, ox) == "1" ? kCharge : kDischarge;
  }
  raw.start_epoch_s = start_epoch_s;
  raw.charge_positive = true;  // EC-Lab: oxidation (charging the cell) positive
  return raw;
}

RawColumns read_nasa(const DelimitedTable& t) {
  RawColumns raw;
  const char* L = "NASA PCoE";
  const std::size_t tc = require(t, column_named(t, {"time"}), "time", L, "Time");
  const std::size_t cc = require(t, column_named(t, {"currentmeasured"}), "current", L, "Current_measured");
  const std::size_t vc = require(t, column_named(t, {"voltagemeasured"}), "voltage", L, "Voltage_measured");
  raw.time_col = tc;
  raw.current_col = cc;
  raw.t_s = t.numbers(tc);  // the data set's units: s, A, V, degC
  raw.current_a = t.numbers(cc);
  raw.voltage_v = t.numbers(vc);
  check_voltage(t, raw.voltage_v, vc);
  raw.cycle.assign(t.rows(), 0);
  raw.step.assign(t.rows(), 0);
  const std::size_t temp = column_named(t, {"temperaturemeasured"});
  if (temp != DelimitedTable::npos) {
    raw.temperature_k = t.numbers(temp);
    for (std::size_t r = 0; r < t.rows(); ++r) {
      if (raw.temperature_k[r] < -100.0 || raw.temperature_k[r] > 200.0)
        throw InputError(fmt::format("{}: temperature {} degC outside -100..200", t.where(r, temp), raw.temperature_k[r]));
      raw.temperature_k[r] += kCelsiusOffsetK;
    }
  }
  raw.charge_positive = true;  // NASA PCoE: Current_measured negative on discharge
  return raw;
}

// The cycler's per-cycle capacities and internal resistance (Arbin columns), cycles as in the file.
std::vector<CyclerCycleStat> arbin_cycle_stats(const DelimitedTable& t, const RawColumns& raw) {
  const std::size_t ch = column_named(t, {"chargecapacity"}), dis = column_named(t, {"dischargecapacity"});
  const std::size_t ir = column_named(t, {"internalresistance"});
  if (dis == DelimitedTable::npos) return {};
  const std::vector<double> d = t.numbers(dis);
  const std::vector<double> c = ch == DelimitedTable::npos ? std::vector<double>(d.size(), std::nan("")) : t.numbers(ch);
  const std::vector<double> res = ir == DelimitedTable::npos ? std::vector<double>(d.size(), 0.0) : t.numbers(ir);
  std::vector<CyclerCycleStat> out;
  std::size_t first = 0;
  for (std::size_t r = 0; r < d.size(); ++r) {
    if (r + 1 < d.size() && raw.cycle[r + 1] == raw.cycle[r]) continue;
    CyclerCycleStat s{raw.cycle[r], raw.t_s[r], 0.0, 0.0, std::nan("")};
    double dmin = d[first], dmax = d[first], cmin = c[first], cmax = c[first];
    for (std::size_t k = first; k <= r; ++k) {
      dmin = std::min(dmin, d[k]);
      dmax = std::max(dmax, d[k]);
      cmin = std::min(cmin, c[k]);
      cmax = std::max(cmax, c[k]);
      if (res[k] > 0.0) s.internal_resistance_ohm = res[k];
    }
    s.discharge_ah = dmax - dmin;
    s.charge_ah = cmax - cmin;
    out.push_back(s);
    first = r + 1;
  }
  return out;
}

bool has_all(const std::vector<std::string>& quantities, std::initializer_list<std::string_view> names) {
  for (std::string_view n : names)
    if (std::find(quantities.begin(), quantities.end(), n) == quantities.end()) return false;
  return true;
}
bool has_any(const std::vector<std::string>& quantities, std::initializer_list<std::string_view> names) {
  for (std::string_view n : names)
    if (std::find(quantities.begin(), quantities.end(), n) != quantities.end()) return true;
  return false;
}

CyclerLayout layout_of_header(const std::vector<std::string>& cells) {
  std::vector<std::string> q;
  for (const auto& c : cells) q.push_back(parts_of(c).quantity);
  if (has_all(q, {"voltagemeasured", "currentmeasured", "time"})) return CyclerLayout::nasa;
  if (has_all(q, {"filename", "starttime"})) return CyclerLayout::nasa_index;
  if (has_any(q, {"testtime"}) && has_any(q, {"current"}) && has_any(q, {"voltage"})) {
    if (has_any(q, {"datapoint", "stepindex"})) return CyclerLayout::arbin;
    if (has_any(q, {"cycleindex"}) && has_any(q, {"chargetime", "dischargetime"}))
      return CyclerLayout::arbin_statistics;
  }
  if (has_any(q, {"rec#", "rec"}) && has_any(q, {"amps", "current"}) && has_any(q, {"volts", "voltage"}))
    return CyclerLayout::maccor;
  if (has_any(q, {"stepname", "steptype", "cycleid", "stepid", "recordid", "recordindex"}) &&
      has_any(q, {"current"}) && has_any(q, {"voltage"}))
    return CyclerLayout::neware;
  if (has_any(q, {"time"}) && has_any(q, {"ewe", "ecell", "<ewe>"}) && has_any(q, {"i", "<i>"}))
    return CyclerLayout::biologic;
  return CyclerLayout::none;
}

std::vector<std::string_view> first_lines(std::string_view text, std::size_t n) {
  std::vector<std::string_view> lines;
  while (!text.empty() && lines.size() < n) {
    const auto nl = text.find('\n');
    std::string_view l = text.substr(0, nl);
    if (!l.empty() && l.back() == '\r') l.remove_suffix(1);
    lines.push_back(l);
    text.remove_prefix(nl == std::string_view::npos ? text.size() : nl + 1);
  }
  return lines;
}

// EC-Lab: "Nb header lines : N" on line 2; the header is line N.
CyclerLayoutGuess biologic_guess(const std::vector<std::string_view>& lines) {
  CyclerLayoutGuess g;
  if (lines.size() < 2 || lines[0].find("ASCII FILE") == std::string_view::npos) return g;
  const auto colon = lines[1].find(':');
  if (lines[1].find("header lines") == std::string_view::npos || colon == std::string_view::npos) return g;
  double n = 0;
  if (!parse_duration_s(lines[1].substr(colon + 1), n) || n < 1 || n != std::floor(n)) return g;
  g.layout = CyclerLayout::biologic;
  g.header_line = static_cast<std::size_t>(n) - 1;
  g.delimiter = '\t';
  return g;
}

double biologic_start(std::string_view text, std::size_t header_line) {
  for (std::string_view l : first_lines(text, header_line)) {
    const auto at = l.find("Acquisition started on");
    if (at == std::string_view::npos) continue;
    double s = 0.0;
    const auto colon = l.find(':', at);
    if (colon != std::string_view::npos && parse_date_time_s(l.substr(colon + 1), s)) return s;
  }
  return std::nan("");
}

}  // namespace

std::string_view cycler_layout_name(CyclerLayout layout) {
  switch (layout) {
    case CyclerLayout::arbin: return "Arbin";
    case CyclerLayout::arbin_statistics: return "Arbin statistics";
    case CyclerLayout::maccor: return "Maccor";
    case CyclerLayout::neware: return "Neware";
    case CyclerLayout::biologic: return "BioLogic";
    case CyclerLayout::nasa: return "NASA PCoE";
    case CyclerLayout::nasa_index: return "NASA PCoE index";
    case CyclerLayout::none: break;
  }
  return "none";
}

CyclerLayoutGuess detect_cycler_layout(std::string_view head) {
  constexpr std::string_view kBom = "\xEF\xBB\xBF";
  if (head.substr(0, kBom.size()) == kBom) head.remove_prefix(kBom.size());
  const std::vector<std::string_view> lines = first_lines(head, 64);
  CyclerLayoutGuess g = biologic_guess(lines);
  if (g.layout != CyclerLayout::none) return g;
  // The header is the first of the first lines whose cells name a layout (Maccor has a metadata
  // line first); tab-, comma- or semicolon-separated (a European locale's CSV), whichever gives
  // more cells.
  for (std::size_t i = 0; i < lines.size() && i < 16; ++i) {
    const auto tabs = std::count(lines[i].begin(), lines[i].end(), '\t');
    const auto commas = std::count(lines[i].begin(), lines[i].end(), ',');
    const auto semicolons = std::count(lines[i].begin(), lines[i].end(), ';');
    const char d = semicolons > std::max(tabs, commas) ? ';' : tabs > commas ? '\t' : ',';
    const CyclerLayout l = layout_of_header(split_delimited(lines[i], d));
    if (l != CyclerLayout::none) return {l, i, d};
  }
  return g;
}

CyclerLayoutGuess detect_cycler_layout_of(const std::filesystem::path& file) {
  // A FIFO or device would block the read; read_text_file refuses it with its reason.
  std::error_code ec;
  if (!std::filesystem::is_regular_file(file, ec)) return {};
  std::ifstream in(file, std::ios::binary);
  if (!in) return {};
  std::string head(64 * 1024, '\0');
  in.read(head.data(), static_cast<std::streamsize>(head.size()));
  head.resize(static_cast<std::size_t>(in.gcount()));
  return detect_cycler_layout(head);
}

CyclerFile parse_cycler_file(std::string text, const std::string& name, CurrentSign sign) {
  const CyclerLayoutGuess g = detect_cycler_layout(std::string_view(text).substr(0, 64 * 1024));
  if (g.layout == CyclerLayout::none || g.layout == CyclerLayout::arbin_statistics ||
      g.layout == CyclerLayout::nasa_index)
    throw InputError(fmt::format("{}: line 1: not a cycler time series (layout: {})", name,
                                 cycler_layout_name(g.layout)));
  const double bio_start = g.layout == CyclerLayout::biologic ? biologic_start(text, g.header_line) : std::nan("");
  const DelimitedTable t(std::move(text), name, g.header_line, g.delimiter);
  if (t.rows() < 2) throw InputError(fmt::format("{}: needs at least 2 data rows, has {}", name, t.rows()));
  RawColumns raw = g.layout == CyclerLayout::arbin    ? read_arbin(t)
                   : g.layout == CyclerLayout::maccor ? read_maccor(t)
                   : g.layout == CyclerLayout::neware ? read_neware(t)
                   : g.layout == CyclerLayout::nasa   ? read_nasa(t)
                                                      : read_biologic(t, bio_start);
  check_time(t, raw);
  CyclerFile f;
  f.sign_note = settle_sign(t, raw, sign);
  check_sign_against_voltage(t, raw, f.sign_note);
  if (g.layout == CyclerLayout::arbin) f.cycle_stats = arbin_cycle_stats(t, raw);
  f.name = name;
  f.layout = g.layout;
  f.start_epoch_s = raw.start_epoch_s;
  f.no_start_why = std::move(raw.no_start_why);
  f.time_column = t.columns()[raw.time_col];
  f.current_column = t.columns()[raw.current_col];
  f.line.resize(t.rows());
  for (std::size_t r = 0; r < t.rows(); ++r) f.line[r] = t.line_of_row(r);
  f.t_s = std::move(raw.t_s);
  f.current_a = std::move(raw.current_a);
  f.voltage_v = std::move(raw.voltage_v);
  f.temperature_k = std::move(raw.temperature_k);
  f.cycle = std::move(raw.cycle);
  f.step = std::move(raw.step);
  f.step_time_s = std::move(raw.step_time_s);
  return f;
}

}  // namespace bms
