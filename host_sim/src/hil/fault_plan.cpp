#include "hil/fault_plan.hpp"

#include <cmath>
#include <cstdlib>
#include <random>

#include "io/input_error.hpp"
#include "sim/cycler.hpp"

namespace bms::hil {

namespace {

constexpr std::size_t kWindowMargin = 10;

[[noreturn]] void bad(const std::string& item, const std::string& why) {
  throw InputError("--fault: '" + item + "': " + why);
}

double parse_double(const std::string& item, const std::string& v) {
  char* end = nullptr;
  const double x = std::strtod(v.c_str(), &end);
  if (v.empty() || end != v.c_str() + v.size() || !std::isfinite(x)) bad(item, "'" + v + "' is not a number");
  return x;
}

std::size_t parse_count(const std::string& item, const std::string& v, const char* what = "ticks") {
  const double x = parse_double(item, v);
  if (x < 0 || x != std::floor(x) || x > 1e9) bad(item, "'" + v + "' is not a whole number" + (*what != '\0' ? std::string(" of ") + what : std::string()));
  return static_cast<std::size_t>(x);
}

double parse_probability(const std::string& item, const std::string& v) {
  const double p = parse_double(item, v);
  if (p < 0.0 || p > 1.0) bad(item, "probability must be in 0..1");
  return p;
}

bool window_kind(const std::string& key, WindowKind& k) {
  static const std::pair<const char*, WindowKind> kinds[] = {
      {"burst", WindowKind::burst}, {"stale", WindowKind::stale},     {"range", WindowKind::range},
      {"nan", WindowKind::nan},     {"busdown", WindowKind::busdown}, {"kill", WindowKind::kill}};
  for (const auto& [name, kind] : kinds)
    if (key == name) {
      k = kind;
      return true;
    }
  return false;
}

// START is a tick number or MODE+SECONDS.
std::size_t resolve_start(const FaultWindow& w, const std::vector<fw::Mode>& modes, double dt_s) {
  const std::string& s = w.start_text;
  const auto plus = s.find('+');
  if (plus == std::string::npos) return parse_count(s, s, "ticks (or MODE+SECONDS)");
  fw::Mode mode{};
  if (!parse_mode(s.substr(0, plus), mode))
    bad(s, "'" + s.substr(0, plus) + "' is not a mode (rest, cc_discharge, cv_discharge, cc_charge, cv_charge)");
  const double after_s = parse_double(s, s.substr(plus + 1));
  if (after_s < 0.0 || after_s > 1e9) bad(s, "SECONDS must be 0..1e9");
  if (modes.empty()) return 0;  // syntax check only
  for (std::size_t k = 0; k < modes.size(); ++k)
    if (modes[k] == mode) return k + static_cast<std::size_t>(std::lround(after_s / dt_s));
  bad(s, "the run has no " + s.substr(0, plus) + " phase");
}

}  // namespace

const char* window_kind_name(WindowKind k) {
  switch (k) {
    case WindowKind::burst: return "burst";
    case WindowKind::stale: return "stale";
    case WindowKind::range: return "range";
    case WindowKind::nan: return "nan";
    case WindowKind::busdown: return "busdown";
    case WindowKind::kill: return "kill";
  }
  return "?";
}

bool FaultSpec::any() const {
  return drop > 0 || dup > 0 || reorder > 0 || crc > 0 || length > 0 || unknown > 0 || !windows.empty();
}

FaultSpec parse_fault_spec(const std::string& text) {
  FaultSpec f;
  f.text = text;
  std::size_t pos = 0;
  while (pos <= text.size()) {
    const std::size_t comma = std::min(text.find(',', pos), text.size());
    const std::string item = text.substr(pos, comma - pos);
    pos = comma + 1;
    if (item.empty()) {
      if (comma == text.size()) break;
      bad(item, "empty item");
    }
    const auto eq = item.find('=');
    if (eq == std::string::npos) bad(item, "expected KEY=VALUE");
    const std::string key = item.substr(0, eq), v = item.substr(eq + 1);
    WindowKind wk{};
    if (key == "drop") f.drop = parse_probability(item, v);
    else if (key == "dup") f.dup = parse_probability(item, v);
    else if (key == "reorder") f.reorder = parse_probability(item, v);
    else if (key == "crc") f.crc = parse_probability(item, v);
    else if (key == "length") f.length = parse_probability(item, v);
    else if (key == "unknown") f.unknown = parse_probability(item, v);
    else if (key == "seed") f.seed = parse_count(item, v, "");
    else if (window_kind(key, wk)) {
      const auto colon = v.rfind(':');
      if (colon == std::string::npos) bad(item, "expected START:TICKS");
      const std::size_t n = parse_count(item, v.substr(colon + 1));
      if (n == 0) bad(item, "the window needs at least 1 tick");
      f.windows.push_back({wk, v.substr(0, colon), 0, n});
      resolve_start(f.windows.back(), {}, 1.0);  // the syntax now; the phase once the run is known
    } else {
      bad(item, "unknown fault (drop, dup, reorder, crc, length, unknown, burst, stale, range, nan, busdown, kill, seed)");
    }
  }
  // Checked with the syntax, before any work (FaultPlan checks it again).
  if (f.drop + f.dup + f.reorder + f.crc + f.length + f.unknown > 1.0) bad(text, "the rates add up to more than 1");
  return f;
}

FaultPlan::FaultPlan(FaultSpec spec, const std::vector<fw::Mode>& modes, double dt_s)
    : spec_(std::move(spec)), ticks_(modes.size()) {
  const std::size_t n = modes.size();
  for (auto& w : spec_.windows) {
    w.start_tick = resolve_start(w, modes, dt_s);
    // A window must end before the run does: the recovery after it is what is measured.
    if (w.start_tick + w.ticks >= n)
      bad(std::string(window_kind_name(w.kind)) + "=" + w.start_text + ":" + std::to_string(w.ticks),
          "the window does not end before the run's last tick " + std::to_string(n - 1));
    for (std::size_t k = w.start_tick; k < w.start_tick + w.ticks; ++k) {
      TickFaults& t = ticks_[k];
      switch (w.kind) {
        case WindowKind::burst: t.drop = true; break;
        case WindowKind::stale: t.stale = true; break;
        case WindowKind::range: t.range = true; break;
        case WindowKind::nan: t.nan = true; break;
        case WindowKind::busdown: t.bus_down = true; break;
        case WindowKind::kill: t.fw_down = true; break;
      }
    }
    if (w.kind == WindowKind::busdown) {
      ticks_[w.start_tick].down_now = true;
      ticks_[w.start_tick + w.ticks].up_now = true;
    }
    if (w.kind == WindowKind::kill) {
      ticks_[w.start_tick].kill_now = true;
      ticks_[w.start_tick + w.ticks].restart_now = true;
    }
  }
  // At most one rate fault per tick (one uniform draw per tick, the kinds stacked in a fixed
  // order), none within kWindowMargin ticks of a window, and a swapped pair's second tick
  // takes none: each fault then has one predictable effect on the receiver's counters,
  // which is what the test checks the firmware's counters against.
  const double total = spec_.drop + spec_.dup + spec_.reorder + spec_.crc + spec_.length + spec_.unknown;
  if (total > 1.0) bad(spec_.text, "the rates add up to more than 1");
  std::vector<bool> quiet(n, false);
  for (const auto& w : spec_.windows) {
    const std::size_t lo = w.start_tick > kWindowMargin ? w.start_tick - kWindowMargin : 0;
    for (std::size_t k = lo; k < std::min(n, w.start_tick + w.ticks + kWindowMargin); ++k) quiet[k] = true;
  }
  std::mt19937_64 rng(spec_.seed);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  for (std::size_t k = 0; k + 1 < n; ++k) {  // the last tick stays clean (nothing to swap with)
    const double r = u(rng);
    TickFaults& t = ticks_[k];
    if (quiet[k] || (k > 0 && ticks_[k - 1].reorder)) continue;
    double edge = 0.0;
    auto pick = [&r, &edge](double p) {
      const bool hit = r >= edge && r < edge + p;
      edge += p;
      return hit;
    };
    if (pick(spec_.drop)) t.drop = true;
    else if (pick(spec_.dup)) t.dup = true;
    else if (pick(spec_.reorder)) t.reorder = !quiet[k + 1];
    else if (pick(spec_.crc)) t.crc = true;
    else if (pick(spec_.length)) t.length = true;
    else if (pick(spec_.unknown)) t.unknown = true;
  }
}

}  // namespace bms::hil
