// Fuzz target: the CSV reader and the measured-profile reader on top of it
// (host_sim/src/io/csv_table.*, measured_profile.*). Input: byte 0 picks the reader
// (0: the table, every column read as numbers and `mode` as text; 1: a truth/About:Energy
// profile with the truth columns; 2: with the measured columns), the rest is the file.
// Every problem must be an InputError; accepted data must hold what the readers promise.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <string_view>

#include "io/csv_table.hpp"
#include "io/input_error.hpp"
#include "io/measured_profile.hpp"

namespace {

void table(std::string_view text) {
  const bms::CsvTable t = bms::parse_csv(text, "fuzz.csv", {"mode"});
  for (const std::string& c : t.columns()) {
    if (c == "mode") {
      if (t.strings(c).size() != t.rows()) std::abort();
      continue;
    }
    try {
      const std::vector<double>& v = t.numbers(c);
      if (v.size() != t.rows()) std::abort();
      for (double x : v) {
        if (!std::isfinite(x)) std::abort();  // the reader promises finite numbers
      }
    } catch (const bms::InputError&) {
    }
    if (t.rows() > 0) (void)t.where(t.rows() - 1, c);
  }
}

void profile(std::string_view text, bms::ProfileColumns which) {
  const bms::MeasuredProfile p = bms::parse_measured_profile(text, "fuzz.csv", which);
  const std::size_t n = p.t_s.size();
  if (n < 2 || p.current_a.size() != n || p.voltage_v.size() != n) std::abort();
  if (!p.temperature_k.empty() && p.temperature_k.size() != n) std::abort();
  if (!p.mode.empty() && p.mode.size() != n) std::abort();
  for (std::size_t i = 1; i < n; ++i) {
    if (!(p.t_s[i] > p.t_s[i - 1])) std::abort();
  }
  for (std::size_t i = 0; i < n; ++i) {
    if (!(p.voltage_v[i] >= 0.0 && p.voltage_v[i] <= 10.0) || !std::isfinite(p.current_a[i])) std::abort();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::string_view text(reinterpret_cast<const char*>(data) + 1, size - 1);
  try {
    switch (data[0] % 3u) {
      case 0: table(text); break;
      case 1: profile(text, bms::ProfileColumns::truth); break;
      default: profile(text, bms::ProfileColumns::measured); break;
    }
  } catch (const bms::InputError& e) {
    if (std::string_view(e.what()).substr(0, 9) != "fuzz.csv:") std::abort();
  }
  return 0;
}
