#include "sim/experiment.hpp"

#include <cctype>
#include <cmath>
#include <cstdlib>
#include <sstream>

#include "io/input_error.hpp"

namespace bms {

Experiment cccv_experiment(const CccvProtocol& protocol) {
  if (!(protocol.v_min < protocol.v_max))
    throw InputError("voltage limits inverted: lower " + std::to_string(protocol.v_min) +
                     " V must be below upper " + std::to_string(protocol.v_max) + " V");
  if (!(protocol.current_a > 0.0)) throw InputError("--current-a must be positive (a magnitude)");
  if (!(protocol.cv_end_current_a > 0.0 && protocol.cv_end_current_a < protocol.current_a))
    throw InputError("--cv-end-current-a " + std::to_string(protocol.cv_end_current_a) +
                     " A: must be positive and below the CC current " + std::to_string(protocol.current_a) +
                     " A (a CV phase starts at the CC current and ends when it falls below this)");
  Experiment e;
  e.cycles = protocol.cycles;
  e.max_step_s = protocol.max_mode_s;
  auto step = [](Mode mode, ControlKind kind, double value, const char* text) {
    ExperimentStep s;
    s.mode = mode;
    s.kind = kind;
    s.value = value;
    s.text = text;
    return s;
  };
  e.steps.push_back(step(Mode::cc_discharge, ControlKind::current, protocol.current_a, "cc_discharge"));
  e.steps.back().until_voltage_v = protocol.v_min;
  e.steps.push_back(step(Mode::cv_discharge, ControlKind::voltage, protocol.v_min, "cv_discharge"));
  e.steps.back().until_abs_current_a = protocol.cv_end_current_a;
  e.steps.push_back(step(Mode::cc_charge, ControlKind::current, -protocol.current_a, "cc_charge"));
  e.steps.back().until_voltage_v = protocol.v_max;
  e.steps.push_back(step(Mode::cv_charge, ControlKind::voltage, protocol.v_max, "cv_charge"));
  e.steps.back().until_abs_current_a = protocol.cv_end_current_a;
  return e;
}

namespace {

struct Quantity {
  double value = 0.0;
  std::string unit;  // a, c, v, s (normalised)
};

class StepParser {
 public:
  StepParser(const std::string& text, int number, double capacity_ah) : text_(text), capacity_ah_(capacity_ah) {
    std::istringstream in(text);
    for (std::string w; in >> w;) {
      for (auto& ch : w) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
      words_.push_back(w);
    }
    where_ = "--protocol step " + std::to_string(number) + " '" + trimmed(text) + "'";
  }

  ExperimentStep parse() {
    ExperimentStep s;
    s.text = trimmed(text_);
    const std::string verb = next("a step (Discharge, Charge, Rest or Hold)");
    if (verb == "discharge" || verb == "charge") {
      expect("at");
      const Quantity q = quantity("a current (A, mA or a C rate)");
      const double amps = to_amps(q);
      s.mode = verb == "discharge" ? Mode::cc_discharge : Mode::cc_charge;
      s.kind = ControlKind::current;
      s.value = verb == "discharge" ? amps : -amps;
    } else if (verb == "rest") {
      s.mode = Mode::rest;
      s.kind = ControlKind::current;
      s.value = 0.0;
    } else if (verb == "hold") {
      expect("at");
      const Quantity q = quantity("a voltage in V");
      if (q.unit != "v") fail("hold needs a voltage in V");
      s.kind = ControlKind::voltage;
      s.value = q.value;
      s.mode = Mode::cv_charge;  // the caller picks the side from the neighbouring steps
    } else {
      fail("unknown step '" + verb + "': use Discharge, Charge, Rest or Hold (power and resistance steps are not supported)");
    }
    endings(s);
    return s;
  }

 private:
  static std::string trimmed(const std::string& t) {
    const auto a = t.find_first_not_of(" \t\r\n");
    const auto b = t.find_last_not_of(" \t\r\n");
    return a == std::string::npos ? std::string() : t.substr(a, b - a + 1);
  }
  [[noreturn]] void fail(const std::string& why) const { throw InputError(where_ + ": " + why); }
  std::string next(const char* what) {
    if (pos_ >= words_.size()) fail(std::string("expected ") + what + " at the end");
    return words_[pos_++];
  }
  void expect(const char* word) {
    const std::string w = next(word);
    if (w != word) fail("expected '" + std::string(word) + "', found '" + w + "'");
  }

  // "2.5", "2.5A", "2.5 a", "50ma", "1c", "c/20", "30 minutes", "1 hour"
  Quantity quantity(const char* what) {
    std::string w = next(what);
    Quantity q;
    if (w.rfind("c/", 0) == 0) {
      const double n = number(w.substr(2), what);
      if (!(n > 0.0)) fail(std::string("expected ") + what + ", found '" + w + "'");
      return {1.0 / n, "c"};
    }
    const char* begin = w.c_str();
    char* end = nullptr;
    q.value = std::strtod(begin, &end);
    if (end == begin) fail(std::string("expected ") + what + ", found '" + w + "'");
    std::string unit(end);
    if (unit.empty()) {
      if (pos_ >= words_.size()) fail(std::string("expected the unit of ") + what);
      unit = words_[pos_++];
    }
    q.unit = normalised_unit(unit, q.value);
    if (q.unit.empty()) fail("unknown unit '" + unit + "' in " + what);
    if (!std::isfinite(q.value) || !(q.value > 0.0)) fail(std::string("expected a positive, finite ") + what);
    return q;
  }
  double number(const std::string& w, const char* what) const {
    char* end = nullptr;
    const double v = std::strtod(w.c_str(), &end);
    if (w.empty() || *end != '\0') fail(std::string("expected ") + what + ", found '" + w + "'");
    return v;
  }
  // Scales value to A, V or s in place; returns the base unit, or "" when unknown.
  static std::string normalised_unit(const std::string& u, double& value) {
    if (u == "a") return "a";
    if (u == "ma") { value *= 1e-3; return "a"; }
    if (u == "c") return "c";
    if (u == "v") return "v";
    if (u == "mv") { value *= 1e-3; return "v"; }
    if (u == "s" || u == "sec" || u == "second" || u == "seconds") return "s";
    if (u == "min" || u == "minute" || u == "minutes") { value *= 60.0; return "s"; }
    if (u == "h" || u == "hr" || u == "hour" || u == "hours") { value *= 3600.0; return "s"; }
    return "";
  }
  double to_amps(const Quantity& q) const {
    if (q.unit == "a") return q.value;
    if (q.unit == "c") return q.value * capacity_ah_;
    fail("expected a current (A, mA or a C rate)");
  }

  // "for D", "until X", joined by "or", in any order.
  void endings(ExperimentStep& s) {
    while (pos_ < words_.size()) {
      const std::string w = words_[pos_++];
      if (w == "or") continue;
      if (w == "for") {
        const Quantity q = quantity("a duration (seconds, minutes or hours)");
        if (q.unit != "s") fail("'for' needs a duration (seconds, minutes or hours)");
        s.duration_s = q.value;
      } else if (w == "until") {
        until(s, quantity("a voltage (V) or a current (A, mA, C rate)"));
      } else {
        fail("unexpected '" + w + "'");
      }
    }
    const bool ends = std::isfinite(s.duration_s) || std::isfinite(s.until_voltage_v) || s.until_abs_current_a > 0.0;
    if (!ends) fail("the step never ends: add 'for D minutes' or 'until ...'");
    if (s.mode == Mode::rest && !std::isfinite(s.duration_s)) fail("a rest needs 'for D minutes'");
  }
  void until(ExperimentStep& s, const Quantity& q) {
    if (s.kind == ControlKind::voltage) {
      if (q.unit == "v") fail("a hold ends at a current (A, mA, C rate), not at a voltage");
      s.until_abs_current_a = to_amps(q);
    } else if (s.mode == Mode::rest) {
      fail("a rest ends after a duration ('for D minutes')");
    } else {
      if (q.unit != "v") fail("a constant-current step ends at a voltage ('until 3.6 V')");
      s.until_voltage_v = q.value;
    }
  }

  std::string text_, where_;
  double capacity_ah_;
  std::vector<std::string> words_;
  size_t pos_ = 0;
};

// A hold charges when it follows (or, first in the cycle, precedes) a charge.
void assign_hold_sides(std::vector<ExperimentStep>& steps) {
  const size_t n = steps.size();
  for (size_t i = 0; i < n; ++i) {
    if (steps[i].kind != ControlKind::voltage) continue;
    Mode side = Mode::cv_charge;
    for (size_t k = 1; k <= n; ++k) {
      const Mode m = steps[(i + n - k) % n].mode;
      if (m == Mode::cc_charge || m == Mode::cc_discharge) {
        side = m == Mode::cc_charge ? Mode::cv_charge : Mode::cv_discharge;
        break;
      }
    }
    steps[i].mode = side;
  }
}

}  // namespace

Experiment parse_experiment(const std::string& text, double capacity_ah, int cycles) {
  if (!(capacity_ah > 0.0)) throw InputError("--protocol: the cell has no nominal capacity for C rates");
  Experiment e;
  e.cycles = cycles;
  std::string step;
  std::istringstream in(text);
  int number = 0;
  while (std::getline(in, step, ';')) {
    ++number;
    if (step.find_first_not_of(" \t\r\n") == std::string::npos) {
      if (in.eof()) break;  // a trailing ';'
      throw InputError("--protocol step " + std::to_string(number) + ": empty");
    }
    e.steps.push_back(StepParser(step, number, capacity_ah).parse());
  }
  if (e.steps.empty()) throw InputError("--protocol: no steps (e.g. \"Discharge at 1C until 2.0 V; Rest for 1 hour\")");
  if (e.steps.size() > 1000) throw InputError("--protocol: more than 1000 steps");
  assign_hold_sides(e.steps);
  return e;
}

}  // namespace bms
