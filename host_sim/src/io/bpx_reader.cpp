// BPX 0.1 -> CellParameters, with the interpretation of PyBaMM's BPX reader:
//  - "Transport efficiency" is eps^b itself; electrode "Conductivity" is already effective;
//  - active-material fraction eps_s = a R / 3 from "Surface area per unit volume" (spheres);
//  - j0 = F k sqrt((c_e/c_e0)(c_s/c_max)(1 - c_s/c_max)) with k the normalised
//    "Reaction rate constant", i.e. i0_coefficient = F k / (sqrt(c_e0) c_max);
//  - cell electrode area = "Electrode area" x number of electrode pairs in parallel;
//  - the simulation starts at 100 % state of charge (negative at its maximum stoichiometry,
//    positive at its minimum);
//  - every cell has the Ramadass side reaction: its constants are read from the optional
//    "Parameterisation" / "User-defined" section under PyBaMM's SEI parameter names (see
//    read_side_reaction and docs/parameters.md), else the paper's values apply.
#include "io/bpx_reader.hpp"

#include <fmt/format.h>

#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "io/expression.hpp"
#include "io/input_error.hpp"
#include "io/table_function.hpp"
#include "io/text_file.hpp"

namespace bms {

namespace {

using nlohmann::json;

constexpr double kFaradayC_mol = 96485.33212;  // C/mol, the firmware's value (bms_io builds without the firmware)
constexpr double kInf = std::numeric_limits<double>::infinity();
constexpr double kDefaultReferenceTemperatureK = 298.15;

struct Range {
  double lo, hi;
  bool lo_open, hi_open;

  bool contains(double v) const {
    return (lo_open ? v > lo : v >= lo) && (hi_open ? v < hi : v <= hi);
  }
  std::string text() const {
    if (hi == kInf) return fmt::format("{} {}", lo_open ? ">" : ">=", lo);
    return fmt::format("{}{}, {}{}", lo_open ? '(' : '[', lo, hi, hi_open ? ')' : ']');
  }
};

constexpr Range kOpenFraction{0.0, 1.0, true, true};
constexpr Range kTransportEfficiency{0.0, 1.0, true, false};
constexpr Range kStoichiometry{0.0, 1.0, false, false};
constexpr Range kTransference{0.0, 1.0, false, true};
constexpr Range kVoltage{0.0, 10.0, true, false};
constexpr Range kOcp{-10.0, 10.0, false, false};
constexpr Range kAnyValue{-kInf, kInf, true, true};
constexpr Range kTemperature{173.15, 473.15, false, false};  // kelvin; catches degC typed as K
constexpr Range kSeparatorPorosity{0.0, 1.0, true, false};  // a free-standing electrolyte gap: 1

// Physical ranges: generous (one to several decades beyond any published lithium-ion cell) but
// finite, so that a typing error (a unit prefix, an exponent's sign) is an input error naming
// the field and not a model the solver cannot integrate (a solid diffusivity of 1e10 m2/s
// made it crawl at 1e-8 s steps). Published values for comparison in the comments.
constexpr Range kThickness{1e-7, 5e-3, false, false};           // m; electrodes 10-300 um, separators 5-50 um
constexpr Range kParticleRadius{1e-9, 1e-3, false, false};      // m; 20 nm - 30 um
constexpr Range kSolidDiffusivity{1e-25, 1e-8, false, false};   // m2/s; 1e-19 - 1e-12
constexpr Range kElectrolyteDiffusivity{1e-14, 1e-7, false, false};  // m2/s; 1e-11 - 5e-9
constexpr Range kElectrolyteConductivity{1e-6, 100.0, false, false};  // S/m; 0.01 - 2 at c_e0
constexpr Range kSolidConductivity{1e-6, 1e8, false, false};    // S/m (effective); 0.01 (LFP) - 6e7 (copper)
constexpr Range kMaxConcentration{100.0, 1e6, false, false};    // mol/m3; 1e4 - 1e5
constexpr Range kElectrolyteConcentration{1.0, 1e4, false, false};  // mol/m3; 500 - 2000
constexpr Range kRateConstant{1e-15, 1.0, false, false};        // mol/(m2 s), normalised; 1e-8 - 1e-4
constexpr Range kElectrodeArea{1e-6, 1e3, false, false};        // m2 per pair
constexpr Range kCapacity{1e-6, 1e5, false, false};             // A h
constexpr Range kActivation{0.0, 5e5, false, false};            // J/mol; 1e4 - 1e5
constexpr Range kEntropic{-1e-2, 1e-2, false, false};           // V/K; |dU/dT| < 1e-3
constexpr Range kSpecificHeat{1.0, 1e5, false, false};          // J/(kg K); 800 - 1500
constexpr Range kDensity{1.0, 1e5, false, false};               // kg/m3; 1500 - 3000
constexpr Range kVolume{1e-9, 10.0, false, false};              // m3
constexpr Range kExternalArea{1e-6, 100.0, false, false};       // m2
constexpr Range kAreaPerVolume{1.0, 1e10, false, false};         // 1/m; 1e5 - 1e7
constexpr Range kThermodynamicFactor{0.05, 20.0, false, false};  // -; 1 - 3 in carbonate electrolytes
// Side reaction (Ramadass): PyBaMM's SEI example sets for comparison in the comments.
constexpr Range kSeiPotential{-1.0, 2.0, false, false};          // V vs Li; 0.4
constexpr Range kSeiExchange{1e-20, 1.0, false, false};          // A/m2; 1.5e-7 (PyBaMM), 4e-9 (the paper)
constexpr Range kSeiAlpha{0.0, 1.0, true, true};                 // -; 0.5
constexpr Range kSeiMolarVolume{1e-7, 1e3, false, false};        // m3/mol; 9.6e-5 (PyBaMM), 34.8 (the paper's printed M/rho)
constexpr Range kSeiResistivity{1e-6, 1e9, false, false};        // ohm m; 2e5 (PyBaMM), 1 (the paper's 1/K_p)
constexpr Range kSeiThickness{0.0, 1e-5, false, false};          // m; 5e-9
constexpr Range kSeiResistance{0.0, 1.0, false, false};          // ohm m2; 3.4e-3 (the paper)
// The cell's own effects (User-defined keys; the truth model's ranges, dfn_model.cpp).
constexpr Range kContactResistance{0.0, 1.0, false, false};     // ohm; milliohms
constexpr Range kHysteresisHalfGap{0.0, 0.5, false, false};     // V; 5-20 mV for LFP
constexpr Range kHysteresisRate{0.0, 1e4, true, false};         // per unit of state of charge; 50
constexpr Range kHeatTransfer{0.0, 1e3, false, false};          // W/K; 0.01-1 for an 18650
constexpr Range kParticleSizeSigma{0.0, 1.5, false, false};     // log-space standard deviation; 0.2-0.6
constexpr Range kProfileLog10{-4.0, 2.0, false, false};         // log10 of D(x = 1) / D(knee)
constexpr Range kProfileKnee{0.0, 0.99, false, false};          // stoichiometry
constexpr Range kReactantOhmM2{0.0, 100.0, false, false};        // ohm m2 of particle surface
constexpr Range kReactantLog10{0.0, 6.0, false, false};          // decades of rise to x = 1

// A unit written another way than the schema's: spellings of the same unit (factor 1) and
// scaled ones, per schema unit. Compared without spaces, '^' and '*' ("kJ mol^-1" = "kJ.mol-1").
struct UnitSpelling {
  std::string_view schema, other;
  double factor;  // value in the schema's unit = factor x value in the other
};
constexpr UnitSpelling kUnitSpellings[] = {
    {"J.mol-1", "J/mol", 1.0},         {"J.mol-1", "kJ.mol-1", 1e3},      {"J.mol-1", "kJ/mol", 1e3},
    {"m2.s-1", "m2/s", 1.0},           {"m2.s-1", "cm2.s-1", 1e-4},       {"m2.s-1", "cm2/s", 1e-4},
    {"mol.m-3", "mol/m3", 1.0},        {"mol.m-3", "mol.L-1", 1e3},       {"mol.m-3", "mol/L", 1e3},
    {"mol.m-3", "mol.dm-3", 1e3},      {"mol.m-3", "M", 1e3},             {"m", "mm", 1e-3},
    {"m", "um", 1e-6},                 {"m", "µm", 1e-6},                  {"m", "cm", 1e-2},
    {"m", "nm", 1e-9},                 {"m-1", "1/m", 1.0},                {"m-1", "cm-1", 1e2},
    {"S.m-1", "S/m", 1.0},             {"S.m-1", "mS.cm-1", 0.1},          {"S.m-1", "mS/cm", 0.1},
    {"S.m-1", "S.cm-1", 100.0},        {"S.m-1", "S/cm", 100.0},           {"A.h", "Ah", 1.0},
    {"A.h", "mA.h", 1e-3},             {"A.h", "mAh", 1e-3},               {"m2", "cm2", 1e-4},
    {"m3", "cm3", 1e-6},               {"m3", "L", 1e-3},                  {"m3", "mL", 1e-6},
    {"V", "mV", 1e-3},                 {"V.K-1", "V/K", 1.0},              {"V.K-1", "mV.K-1", 1e-3},
    {"V.K-1", "mV/K", 1e-3},           {"kg.m-3", "kg/m3", 1.0},           {"kg.m-3", "g.cm-3", 1e3},
    {"kg.m-3", "g/cm3", 1e3},          {"J.K-1.kg-1", "J.kg-1.K-1", 1.0},  {"J.K-1.kg-1", "J/(kg.K)", 1.0},
    {"J.K-1.kg-1", "J/kg/K", 1.0},     {"J.K-1.kg-1", "J/(K.kg)", 1.0},    {"mol.m-2.s-1", "mol/(m2.s)", 1.0},
    {"mol.m-2.s-1", "mol/m2/s", 1.0},  {"W.m-1.K-1", "W/(m.K)", 1.0},      {"W.m-1.K-1", "W/m/K", 1.0},
};

std::string unit_text(std::string_view u) {
  std::string out;
  for (char c : u)
    if (c != ' ' && c != '^') out.push_back(c == '*' ? '.' : c);
  return out;
}

// "Diffusivity [m2.s-1]" -> {"Diffusivity", "m2.s-1"}; no unit: {key, ""}.
std::pair<std::string, std::string> split_key(std::string_view key) {
  const auto open = key.rfind(" [");
  if (open == std::string_view::npos || key.back() != ']') return {std::string(key), {}};
  return {std::string(key.substr(0, open)), std::string(key.substr(open + 2, key.size() - open - 3))};
}

// The factor from `other` to the schema's unit, or NaN when it is not one this reader knows.
double unit_factor(std::string_view schema, std::string_view other) {
  const std::string s = unit_text(schema), o = unit_text(other);
  if (s == o) return 1.0;
  for (const auto& u : kUnitSpellings)
    if (unit_text(u.schema) == s && unit_text(u.other) == o) return u.factor;
  return std::numeric_limits<double>::quiet_NaN();
}

// One JSON object of the file, with its dotted path for messages.
class Section {
 public:
  Section(const json& j, std::string path, const std::string& file)
      : j_(j), path_(std::move(path)), file_(file) {}

  std::string field(std::string_view key) const {
    return path_.empty() ? std::string(key) : fmt::format("{}.{}", path_, key);
  }
  [[noreturn]] void fail(std::string_view key, std::string_view problem) const {
    throw InputError(fmt::format("{}: field '{}' {}", file_, field(key), problem));
  }

  // The value of `key`, or of the same quantity with its unit written another way (converted
  // by factor_ on reading it); nullptr when absent. A unit it cannot convert fails naming the key.
  const json* find(std::string_view key) const {
    factor_ = 1.0;
    used_key_ = std::string(key);
    const auto it = j_.find(key);
    if (it != j_.end()) {
      used_.insert(std::string(key));
      return &*it;
    }
    const auto [quantity, unit] = split_key(key);
    if (unit.empty()) return nullptr;
    for (auto e = j_.begin(); e != j_.end(); ++e) {
      const auto [q, u] = split_key(e.key());
      if (q != quantity || u.empty()) continue;
      const double f = unit_factor(unit, u);
      if (!std::isfinite(f))
        fail(e.key(), fmt::format("has a unit this reader cannot convert to the schema's [{}]; write it in [{}]",
                                  unit, unit));
      used_.insert(e.key());
      used_key_ = e.key();
      factor_ = f;
      return &*e;
    }
    return nullptr;
  }

  // Every key of the section must be one the schema has (read above, or in `unused`, the
  // schema's keys this model does not need): an unknown one is never dropped silently.
  void refuse_unknown(std::initializer_list<std::string_view> unused) const {
    for (auto e = j_.begin(); e != j_.end(); ++e) {
      if (used_.count(e.key()) != 0) continue;
      bool known = false;
      for (std::string_view u : unused) known = known || split_key(e.key()).first == split_key(u).first;
      if (!known) fail(e.key(), "is not a key of the BPX schema's section (a typing error, or a unit in place of the "
                                "quantity's name?); remove or rename it");
    }
  }
  const json& get(std::string_view key) const {
    const json* v = find(key);
    if (v == nullptr) throw InputError(fmt::format("{}: missing field '{}'", file_, field(key)));
    return *v;
  }

  Section section(std::string_view key) const {
    const json& v = get(key);
    if (!v.is_object()) fail(key, fmt::format("must be an object, not {}", v.type_name()));
    return Section(v, field(key), file_);
  }

  double number(std::string_view key, Range range) const {
    const json& v = get(key);
    return checked(used_key_, v, range, factor_);
  }
  double number_or(std::string_view key, Range range, double fallback) const {
    const json* v = find(key);
    return v == nullptr ? fallback : checked(used_key_, *v, range, factor_);
  }

  // A number, a Python-style expression in x, or an {"x": [...], "y": [...]} table.
  ScalarFunctionPtr function(std::string_view key) const {
    const json& v = get(key);
    return scaled(to_function(used_key_, v), factor_);
  }
  ScalarFunctionPtr function_or_null(std::string_view key) const {
    const json* v = find(key);
    return v == nullptr ? nullptr : scaled(to_function(used_key_, *v), factor_);
  }

  // Functions can only be checked at sample points; a few well-chosen ones catch "x / 0",
  // sign errors and tables that do not cover the range in use.
  void check_function(std::string_view key, const ScalarFunction& f, double x, Range range) const {
    const double v = f.value(x);
    const double d = f.derivative(x);
    if (!std::isfinite(v) || !std::isfinite(d) || !range.contains(v)) {
      fail(key, fmt::format("evaluates to {} (derivative {}) at x = {}; allowed values: {}", v, d,
                            x, range.text()));
    }
  }

 private:
  static ScalarFunctionPtr scaled(ScalarFunctionPtr f, double factor) {
    return factor == 1.0 ? f : std::make_shared<ScaledFunction>(std::move(f), factor);
  }
  double checked(std::string_view key, const json& v, Range range, double factor = 1.0) const {
    if (!v.is_number()) fail(key, fmt::format("must be a number, not {}", v.type_name()));
    const double x = factor * v.get<double>();
    if (!range.contains(x)) {
      fail(key, fmt::format("= {} is out of range (allowed: {})", x, range.text()));
    }
    return x;
  }

  ScalarFunctionPtr to_function(std::string_view key, const json& v) const {
    if (v.is_number()) return std::make_shared<ConstantFunction>(checked(key, v, kAnyValue));
    const std::string where = fmt::format("{}: field '{}'", file_, field(key));
    if (v.is_string()) return ExpressionFunction::parse(v.get_ref<const std::string&>(), where);
    if (v.is_object() && v.contains("x") && v.contains("y")) {
      return std::make_shared<TableFunction>(numbers(key, "x", v.at("x")),
                                             numbers(key, "y", v.at("y")), where);
    }
    fail(key, fmt::format("must be a number, an expression string or an {{\"x\": [...], "
                          "\"y\": [...]}} table, not {}",
                          v.type_name()));
  }

  std::vector<double> numbers(std::string_view key, std::string_view axis, const json& v) const {
    const std::string name = fmt::format("{}.{}", key, axis);
    if (!v.is_array()) {
      fail(name, fmt::format("must be an array of numbers, not {}", v.type_name()));
    }
    std::vector<double> out;
    out.reserve(v.size());
    for (const json& e : v) {
      if (!e.is_number()) {
        fail(fmt::format("{}[{}]", name, out.size()),
             fmt::format("must be a number, not {}", e.type_name()));
      }
      out.push_back(e.get<double>());
    }
    return out;
  }

  const json& j_;
  std::string path_;
  const std::string& file_;
  mutable std::set<std::string> used_;
  mutable std::string used_key_;  // the key find() read (the schema's, or its other spelling)
  mutable double factor_ = 1.0;   // to the schema's unit
};

void check_version(const Section& header) {
  const json& v = header.get("BPX");
  // BPX 0.1 files write the version as the number 0.1; later ones as a "major.minor.patch" string.
  bool ok = false;
  if (v.is_number()) {
    ok = std::fabs(v.get<double>() - 0.1) < 1e-12;
  } else if (v.is_string()) {
    const std::string& s = v.get_ref<const std::string&>();
    ok = s == "0.1" || s.rfind("0.1.", 0) == 0;
  }
  if (!ok) {
    header.fail(
        "BPX", fmt::format("= {}: unsupported BPX version (this reader supports 0.1.x)", v.dump()));
  }
}

ElectrodeParameters read_electrode(const Section& s, double c_e0, bool negative) {
  if (s.find("Particle") != nullptr) s.fail("Particle", "(blended electrode) is not supported");
  ElectrodeParameters e;
  e.thickness_m = s.number("Thickness [m]", kThickness);
  e.particle_radius_m = s.number("Particle radius [m]", kParticleRadius);
  const double area_per_volume = s.number("Surface area per unit volume [m-1]", kAreaPerVolume);
  e.porosity = s.number("Porosity", kOpenFraction);
  e.transport_efficiency = s.number("Transport efficiency", kTransportEfficiency);
  // Spherical particles: a = 3 eps_s / R.
  e.solid_fraction = area_per_volume * e.particle_radius_m / 3.0;
  if (!(e.solid_fraction + e.porosity <= 1.0 + 1e-9)) {
    s.fail(
        "Surface area per unit volume [m-1]",
        fmt::format("= {} gives an active-material fraction a R / 3 = {} that, with porosity {}, "
                    "exceeds the whole volume",
                    area_per_volume, e.solid_fraction, e.porosity));
  }
  e.max_concentration_mol_m3 = s.number("Maximum concentration [mol.m-3]", kMaxConcentration);
  e.conductivity_eff_s_m = s.number("Conductivity [S.m-1]", kSolidConductivity);

  // BPX: j0 = F k sqrt((c_e/c_e0) (c_s/c_max) (1 - c_s/c_max)), folded into the struct's
  // i0 = i0_coefficient sqrt(c_e c_s (c_max - c_s)).
  const double k_norm = s.number("Reaction rate constant [mol.m-2.s-1]", kRateConstant);
  e.i0_coefficient = kFaradayC_mol * k_norm / (std::sqrt(c_e0) * e.max_concentration_mol_m3);

  e.stoich_min = s.number("Minimum stoichiometry", kStoichiometry);
  e.stoich_max = s.number("Maximum stoichiometry", kStoichiometry);
  if (!(e.stoich_min < e.stoich_max)) {
    s.fail("Minimum stoichiometry",
           fmt::format("= {} must be less than 'Maximum stoichiometry' = {}", e.stoich_min,
                       e.stoich_max));
  }
  // 100 % state of charge: lithium sits in the negative electrode.
  e.stoich_init = negative ? e.stoich_max : e.stoich_min;

  e.diffusivity_activation_j_mol =
      s.number_or("Diffusivity activation energy [J.mol-1]", kActivation, 0.0);
  e.rate_activation_j_mol =
      s.number_or("Reaction rate constant activation energy [J.mol-1]", kActivation, 0.0);

  // A stoichiometry-dependent diffusivity (an expression in x or a table): its value at
  // mid-range, x = 0.5, is the constant the rest of the host uses (the firmware's reduced model,
  // the `--set` scales), and the truth's particles take D(x) / D(0.5) as a factor on it.
  constexpr double kDiffusivityStoichiometry = 0.5;
  const ScalarFunctionPtr diffusivity = s.function("Diffusivity [m2.s-1]");
  for (const double x : {kDiffusivityStoichiometry, e.stoich_min, e.stoich_max})
    s.check_function("Diffusivity [m2.s-1]", *diffusivity, x, kSolidDiffusivity);
  e.solid_diffusivity_m2_s = diffusivity->value(kDiffusivityStoichiometry);
  if (!s.get("Diffusivity [m2.s-1]").is_number())
    e.solid_diffusivity_factor = relative_to(diffusivity, kDiffusivityStoichiometry);

  e.ocp_v = s.function("OCP [V]");
  e.entropic_v_k = s.function_or_null("Entropic change coefficient [V.K-1]");
  for (const double x : {e.stoich_min, 0.5 * (e.stoich_min + e.stoich_max), e.stoich_max}) {
    s.check_function("OCP [V]", *e.ocp_v, x, kOcp);
    if (e.entropic_v_k) {
      s.check_function("Entropic change coefficient [V.K-1]", *e.entropic_v_k, x, kEntropic);
    }
  }
  s.refuse_unknown({"Density [kg.m-3]", "Specific heat capacity [J.K-1.kg-1]", "Thermal conductivity [W.m-1.K-1]"});
  return e;
}

// The file's JSON; InputError naming the file and the place for a syntax error.
json parse_bpx_json(std::string_view text, const std::string& file) {
  json root;
  try {
    root = json::parse(text);
  } catch (const json::parse_error& e) {
    // what() is "[json.exception.parse_error.101] parse error at line L, column C: ..."
    std::string_view detail = e.what();
    const std::size_t tag_end = detail.find("] ");
    if (tag_end != std::string_view::npos) detail.remove_prefix(tag_end + 2);
    throw InputError(fmt::format("{}: not valid JSON (byte {}): {}", file, e.byte, detail));
  } catch (const json::out_of_range& e) {
    // A number beyond double's range ("1e400") is out_of_range.406, not a parse_error
    // (found by fuzzing: it escaped as a non-InputError exception).
    std::string_view detail = e.what();
    const std::size_t tag_end = detail.find("] ");
    if (tag_end != std::string_view::npos) detail.remove_prefix(tag_end + 2);
    throw InputError(fmt::format("{}: not valid JSON: {}", file, detail));
  }
  return root;
}

// The 'Cell' section: geometry, voltage limits, capacity and thermal data.
void read_cell_section(const Section& cell, CellParameters& p) {
  const double area = cell.number("Electrode area [m2]", kElectrodeArea);
  const std::string pairs_key = "Number of electrode pairs connected in parallel to make a cell";
  const double pairs = cell.number(pairs_key, {1.0, 1e4, false, false});
  if (pairs != std::floor(pairs)) {
    cell.fail(pairs_key, fmt::format("= {} must be a whole number", pairs));
  }
  p.electrode_area_m2 = area * pairs;
  p.lower_voltage_v = cell.number("Lower voltage cut-off [V]", kVoltage);
  p.upper_voltage_v = cell.number("Upper voltage cut-off [V]", kVoltage);
  if (!(p.lower_voltage_v < p.upper_voltage_v)) {
    cell.fail("Lower voltage cut-off [V]",
              fmt::format("= {} must be below 'Upper voltage cut-off [V]' = {}", p.lower_voltage_v,
                          p.upper_voltage_v));
  }
  p.nominal_capacity_ah = cell.number("Nominal cell capacity [A.h]", kCapacity);

  ThermalParameters& th = p.thermal;
  th.ambient_temperature_k = cell.number("Ambient temperature [K]", kTemperature);
  th.initial_temperature_k =
      cell.number_or("Initial temperature [K]", kTemperature, th.ambient_temperature_k);
  th.reference_temperature_k =
      cell.number_or("Reference temperature [K]", kTemperature, kDefaultReferenceTemperatureK);
  // Optional in BPX; 0 tells the thermal model they are unknown.
  th.specific_heat_j_kg_k = cell.number_or("Specific heat capacity [J.K-1.kg-1]", kSpecificHeat, 0.0);
  th.density_kg_m3 = cell.number_or("Density [kg.m-3]", kDensity, 0.0);
  th.volume_m3 = cell.number_or("Volume [m3]", kVolume, 0.0);
  th.external_area_m2 = cell.number_or("External surface area [m2]", kExternalArea, 0.0);
  cell.refuse_unknown({"Thermal conductivity [W.m-1.K-1]"});
}

void read_electrolyte_section(const Section& electrolyte, CellParameters& p) {
  ElectrolyteParameters& el = p.electrolyte;
  el.initial_concentration_mol_m3 =
      electrolyte.number("Initial concentration [mol.m-3]", kElectrolyteConcentration);
  p.initial_electrolyte_mol_m3 = el.initial_concentration_mol_m3;
  el.transference_number = electrolyte.number("Cation transference number", kTransference);
  el.diffusivity_m2_s = electrolyte.function("Diffusivity [m2.s-1]");
  el.conductivity_s_m = electrolyte.function("Conductivity [S.m-1]");
  electrolyte.check_function("Diffusivity [m2.s-1]", *el.diffusivity_m2_s,
                             el.initial_concentration_mol_m3, kElectrolyteDiffusivity);
  electrolyte.check_function("Conductivity [S.m-1]", *el.conductivity_s_m,
                             el.initial_concentration_mol_m3, kElectrolyteConductivity);
  // PyBaMM's "Thermodynamic factor" (1 + dln f/dln c), a BPX extension: optional, 1 when absent.
  // Checked across the concentrations a cell visits (c_e0 / 4 to 2.5 c_e0 at high rates).
  el.thermodynamic_factor = electrolyte.function_or_null("Thermodynamic factor");
  if (el.thermodynamic_factor) {
    for (const double f : {0.25, 1.0, 2.5})
      electrolyte.check_function("Thermodynamic factor", *el.thermodynamic_factor,
                                 f * el.initial_concentration_mol_m3, kThermodynamicFactor);
  }
  el.diffusivity_activation_j_mol =
      electrolyte.number_or("Diffusivity activation energy [J.mol-1]", kActivation, 0.0);
  el.conductivity_activation_j_mol =
      electrolyte.number_or("Conductivity activation energy [J.mol-1]", kActivation, 0.0);
  electrolyte.refuse_unknown({});
}

// The Ramadass side reaction's constants (every cell has one). Keys in the optional
// "User-defined" section of "Parameterisation", PyBaMM's SEI parameter names where one exists:
//   "SEI open-circuit potential [V]"                U_sd,ref
//   "SEI reaction exchange current density [A.m-2]" i_0s
//   "SEI growth transfer coefficient"               alpha
//   "SEI partial molar volume [m3.mol-1]"           M_p / rho_p
//   "SEI resistivity [Ohm.m]"                       1 / K_p
//   "Initial SEI thickness [m]"                     R_SEI = thickness x resistivity, or
//   "Initial SEI resistance [Ohm.m2]"               R_SEI itself (this project's key; not both)
// Each missing key takes the paper's value (SideReactionParameters' defaults); the film-growth
// law depends on M_p / (rho_p K_p) only, so the molar volume is kept as M_p at the paper's rho_p.
void read_side_reaction(const Section& params, CellParameters& p) {
  SideReactionParameters& s = p.side;
  s = SideReactionParameters{};
  s.enabled = true;
  if (params.find("User-defined") == nullptr) return;
  const Section u = params.section("User-defined");
  const char* const keys[] = {"SEI open-circuit potential [V]", "SEI reaction exchange current density [A.m-2]",
                              "SEI growth transfer coefficient", "SEI partial molar volume [m3.mol-1]",
                              "SEI resistivity [Ohm.m]", "Initial SEI thickness [m]",
                              "Initial SEI resistance [Ohm.m2]"};
  bool any = false;
  for (const char* k : keys) any = any || u.find(k) != nullptr;
  if (!any) return;
  s.source = "the file's User-defined SEI keys (the paper's value for each one missing)";
  s.reference_potential_v = u.number_or(keys[0], kSeiPotential, s.reference_potential_v);
  s.exchange_current_a_m2 = u.number_or(keys[1], kSeiExchange, s.exchange_current_a_m2);
  s.transfer_coefficient = u.number_or(keys[2], kSeiAlpha, s.transfer_coefficient);
  const double molar_volume = u.number_or(keys[3], kSeiMolarVolume, s.molar_mass_kg_mol / s.density_kg_m3);
  s.molar_mass_kg_mol = molar_volume * s.density_kg_m3;
  const double resistivity = u.number_or(keys[4], kSeiResistivity, 1.0 / s.film_conductivity_s_m);
  s.film_conductivity_s_m = 1.0 / resistivity;
  if (u.find(keys[5]) != nullptr && u.find(keys[6]) != nullptr)
    u.fail(keys[5], fmt::format("and '{}' both given: give one", u.field(keys[6])));
  if (u.find(keys[5]) != nullptr) s.initial_film_resistance_ohm_m2 = u.number(keys[5], kSeiThickness) * resistivity;
  s.initial_film_resistance_ohm_m2 = u.number_or(keys[6], kSeiResistance, s.initial_film_resistance_ohm_m2);
}

// Effects of the cell beyond the plain DFN, from the optional "User-defined" section (this
// project's keys, PyBaMM's name for the contact resistance; docs/parameters.md). Absent = off.
void read_cell_effects(const Section& params, CellParameters& p) {
  if (params.find("User-defined") == nullptr) return;
  const Section u = params.section("User-defined");
  CellEffectParameters& e = p.effects;
  e.contact_resistance_ohm = u.number_or("Contact resistance [Ohm]", kContactResistance, 0.0);
  e.hysteresis_v = u.number_or("OCP hysteresis half-gap [V]", kHysteresisHalfGap, 0.0);
  e.hysteresis_rate_per_soc = u.number_or("OCP hysteresis rate per state of charge [-]", kHysteresisRate, 0.0);
  e.thermal_h_w_per_k = u.number_or("Lumped heat transfer coefficient [W.K-1]", kHeatTransfer, 0.0);
  e.particle_size_sigma = u.number_or("Positive particle-size log-normal standard deviation [-]", kParticleSizeSigma, 0.0);
  e.diffusivity_profile_positive =
      u.number_or("Positive diffusivity profile log10 factor at full lithiation [-]", kProfileLog10, 0.0);
  e.diffusivity_profile_positive_knee =
      u.number_or("Positive diffusivity profile knee stoichiometry [-]", kProfileKnee, 0.5);
  e.resistive_reactant_positive_ohm_m2 =
      u.number_or("Positive resistive reactant resistance [Ohm.m2]", kReactantOhmM2, 0.0);
  e.resistive_reactant_positive_log10 =
      u.number_or("Positive resistive reactant log10 rise at full lithiation [-]", kReactantLog10, 0.0);
  e.resistive_reactant_positive_knee =
      u.number_or("Positive resistive reactant knee stoichiometry [-]", kProfileKnee, 0.5);
}

}  // namespace

CellParameters read_bpx_text(std::string_view text, std::string_view name) {
  const std::string file(name);
  const json root = parse_bpx_json(text, file);
  if (!root.is_object()) {
    throw InputError(fmt::format("{}: not a BPX file: the top level must be a JSON object, not {}",
                                 file, root.type_name()));
  }
  const Section top(root, "", file);
  check_version(top.section("Header"));
  const Section params = top.section("Parameterisation");
  const Section cell = params.section("Cell");
  const Section electrolyte = params.section("Electrolyte");
  const Section separator = params.section("Separator");

  CellParameters p;
  p.name = std::filesystem::path(file).stem().string();
  p.source = file;

  read_cell_section(cell, p);
  read_electrolyte_section(electrolyte, p);
  const ElectrolyteParameters& el = p.electrolyte;
  p.negative =
      read_electrode(params.section("Negative electrode"), el.initial_concentration_mol_m3, true);
  p.positive =
      read_electrode(params.section("Positive electrode"), el.initial_concentration_mol_m3, false);

  p.separator.thickness_m = separator.number("Thickness [m]", kThickness);
  p.separator.porosity = separator.number("Porosity", kSeparatorPorosity);
  p.separator.transport_efficiency = separator.number("Transport efficiency", kTransportEfficiency);
  separator.refuse_unknown({"Density [kg.m-3]", "Specific heat capacity [J.K-1.kg-1]", "Thermal conductivity [W.m-1.K-1]"});

  read_side_reaction(params, p);
  read_cell_effects(params, p);
  return p;
}

CellParameters read_bpx(const std::filesystem::path& file) {
  return read_bpx_text(read_text_file(file), file.string());
}

}  // namespace bms
