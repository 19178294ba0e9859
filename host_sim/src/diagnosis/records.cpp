#include "diagnosis/records.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "io/input_error.hpp"
#include "io/measured_profile.hpp"

namespace bms::diagnosis {

namespace {

// A sample counts as rest below 1 % of the largest current (ADC jitter at rest is ~1 mA).
constexpr double kRestFraction = 0.01;
// Two CC levels closer than this (relative to max |I|) are one level.
constexpr double kLevelTolerance = 0.02;
// A record counts as "one constant current" when at most this share of it is elsewhere
// (the About:Energy files start with one sample at rest before the step).
constexpr double kOffLevelShare = 0.01;

std::vector<Mode> modes_from_current(const std::vector<double>& i, double imax) {
  std::vector<Mode> m(i.size());
  for (std::size_t k = 0; k < i.size(); ++k) {
    const double rest = kRestFraction * imax + 1e-6;
    m[k] = i[k] > rest ? Mode::cc_discharge : (i[k] < -rest ? Mode::cc_charge : Mode::rest);
  }
  return m;
}

}  // namespace

Record make_record(std::string name, std::vector<double> t_s, std::vector<double> current_a,
                   std::vector<double> voltage_v, std::vector<double> temperature_k,
                   std::vector<Mode> mode) {
  Record r;
  r.source = std::move(name);
  const std::size_t n = t_s.size();
  if (current_a.size() != n || voltage_v.size() != n || (!temperature_k.empty() && temperature_k.size() != n) ||
      (!mode.empty() && mode.size() != n))
    throw InputError(r.source + ": columns of different lengths");
  for (std::size_t k = 0; k < n; ++k) {
    if (!std::isfinite(t_s[k]) || !std::isfinite(current_a[k]) || !std::isfinite(voltage_v[k]))
      throw InputError(fmt::format("{}: row {}: non-finite time, current or voltage", r.source, k + 1));
    if (k > 0 && !(t_s[k] > t_s[k - 1]))
      throw InputError(fmt::format("{}: row {}: time {} s does not increase (previous {} s)", r.source, k + 1,
                                   t_s[k], t_s[k - 1]));
  }
  if (n < kMinSamples || t_s.back() - t_s.front() < kMinDurationS)
    throw InputError(fmt::format(
        "{}: too short for a diagnosis: {} samples over {:.1f} s (need at least {} samples over {:.0f} s)",
        r.source, n, n ? t_s.back() - t_s.front() : 0.0, kMinSamples, kMinDurationS));
  r.t_s = std::move(t_s);
  r.current_a = std::move(current_a);
  r.voltage_v = std::move(voltage_v);
  r.temperature_k = std::move(temperature_k);
  double imax = 0.0;
  for (double i : r.current_a) imax = std::max(imax, std::abs(i));
  r.mode = mode.empty() ? modes_from_current(r.current_a, imax) : std::move(mode);
  return r;
}

Record load_record(const std::filesystem::path& file, CurrentSign sign) {
  // NaN, gaps, non-monotonic time and unknown modes are rejected by the shared reader.
  MeasuredProfile p = read_measured_profile(file, ProfileColumns::measured, sign);
  const std::string layout_note = fmt::format("{} layout, current read as {}", p.layout,
                                              p.current_negated ? "charge-positive" : "discharge-positive");
  std::vector<Mode> modes;
  for (const auto& s : p.mode) {
    Mode m = Mode::unknown;
    parse_mode(s, m);
    modes.push_back(m);
  }
  Record r = make_record(file.string(), std::move(p.t_s), std::move(p.current_a), std::move(p.voltage_v),
                         std::move(p.temperature_k), std::move(modes));
  r.layout_note = layout_note;
  return r;
}

std::vector<double> time_since_step_s(const Record& r) {
  double imax = 0.0;
  for (double i : r.current_a) imax = std::max(imax, std::abs(i));
  const double step = 0.05 * imax + 1e-6;
  std::vector<double> out(r.t_s.size(), 0.0);
  double last = r.t_s.front();
  for (std::size_t k = 1; k < out.size(); ++k) {
    if (std::abs(r.current_a[k] - r.current_a[k - 1]) > step) last = 0.5 * (r.t_s[k] + r.t_s[k - 1]);
    out[k] = r.t_s[k] - last;
  }
  out[0] = 0.0;
  return out;
}

std::string Excitation::describe() const {
  if (no_current) return "no current flows (rest only)";
  std::string s = fmt::format("max |I| {:.3g} A, {} CC level(s)", max_abs_current_a, current_levels);
  if (has_discharge) s += ", discharge";
  if (has_charge) s += ", charge";
  if (has_cv) s += ", CV phases";
  s += fmt::format(", {:.0f} % rest", 100.0 * rest_fraction);
  if (constant_current_only) s += fmt::format(" (one constant current only: {:.3g} A)", typical_current_a);
  return s;
}

Excitation analyse_excitation(const Record& r) {
  Excitation e;
  for (double i : r.current_a) e.max_abs_current_a = std::max(e.max_abs_current_a, std::abs(i));
  const double rest = kRestFraction * e.max_abs_current_a + 1e-6;
  std::vector<double> active;
  std::size_t n_rest = 0;
  for (std::size_t k = 0; k < r.current_a.size(); ++k) {
    const double i = r.current_a[k];
    if (std::abs(i) <= rest) {
      ++n_rest;
    } else {
      active.push_back(i);
      (i > 0 ? e.has_discharge : e.has_charge) = true;
    }
    if (r.mode[k] == Mode::cv_charge || r.mode[k] == Mode::cv_discharge) e.has_cv = true;
  }
  e.rest_fraction = static_cast<double>(n_rest) / static_cast<double>(r.current_a.size());
  if (active.empty() || e.max_abs_current_a < 1e-4) {
    e.no_current = true;
    return e;
  }
  std::vector<double> sorted = active;
  std::sort(sorted.begin(), sorted.end());
  e.typical_current_a = sorted[sorted.size() / 2];
  // Distinct levels: runs of sorted currents with small steps between neighbours.
  const double tol = kLevelTolerance * e.max_abs_current_a;
  e.current_levels = 1;
  for (std::size_t k = 1; k < sorted.size(); ++k)
    if (sorted[k] - sorted[k - 1] > tol) ++e.current_levels;
  std::size_t off_level = n_rest;
  for (double i : active)
    if (std::abs(i - e.typical_current_a) > tol) ++off_level;
  e.constant_current_only =
      static_cast<double>(off_level) <= kOffLevelShare * static_cast<double>(r.current_a.size()) && !e.has_cv;
  return e;
}

std::vector<double> state_of_charge(const Record& r, double soc0, double capacity_ah) {
  std::vector<double> soc(r.t_s.size(), soc0);
  for (std::size_t k = 1; k < soc.size(); ++k) {
    const double q_ah = 0.5 * (r.current_a[k] + r.current_a[k - 1]) * (r.t_s[k] - r.t_s[k - 1]) / 3600.0;
    soc[k] = soc[k - 1] - q_ah / capacity_ah;
  }
  return soc;
}

}  // namespace bms::diagnosis
