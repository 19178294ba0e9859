// BPX 0.1 -> CellParameters, with the interpretation of PyBaMM's BPX reader:
//  - "Transport efficiency" is eps^b itself; electrode "Conductivity" is already effective;
//  - active-material fraction eps_s = a R / 3 from "Surface area per unit volume" (spheres);
//  - j0 = F k sqrt((c_e/c_e0)(c_s/c_max)(1 - c_s/c_max)) with k the normalised
//    "Reaction rate constant", i.e. i0_coefficient = F k / (sqrt(c_e0) c_max);
//  - cell electrode area = "Electrode area" x number of electrode pairs in parallel;
//  - the simulation starts at 100 % state of charge (negative at its maximum stoichiometry,
//    positive at its minimum); BPX has no side reaction, so side.enabled = false.
#include "io/bpx_reader.hpp"

#include <fmt/format.h>

#include <cmath>
#include <limits>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

#include "io/expression.hpp"
#include "io/input_error.hpp"
#include "io/table_function.hpp"
#include "io/text_file.hpp"

namespace bms {

namespace {

using nlohmann::json;

constexpr double kFaraday = 96485.33212;  // C/mol
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

constexpr Range kPositive{0.0, kInf, true, true};
constexpr Range kNonNegative{0.0, kInf, false, true};
constexpr Range kOpenFraction{0.0, 1.0, true, true};
constexpr Range kTransportEfficiency{0.0, 1.0, true, false};
constexpr Range kStoichiometry{0.0, 1.0, false, false};
constexpr Range kTransference{0.0, 1.0, false, true};
constexpr Range kVoltage{0.0, 10.0, true, false};
constexpr Range kOcp{-10.0, 10.0, false, false};
constexpr Range kAnyValue{-kInf, kInf, true, true};
constexpr Range kTemperature{173.15, 473.15, false, false};  // kelvin; catches degC typed as K

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

  const json* find(std::string_view key) const {
    const auto it = j_.find(key);
    return it == j_.end() ? nullptr : &*it;
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

  double number(std::string_view key, Range range) const { return checked(key, get(key), range); }
  double number_or(std::string_view key, Range range, double fallback) const {
    const json* v = find(key);
    return v == nullptr ? fallback : checked(key, *v, range);
  }

  // A number, a Python-style expression in x, or an {"x": [...], "y": [...]} table.
  ScalarFunctionPtr function(std::string_view key) const { return to_function(key, get(key)); }
  ScalarFunctionPtr function_or_null(std::string_view key) const {
    const json* v = find(key);
    return v == nullptr ? nullptr : to_function(key, *v);
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
  double checked(std::string_view key, const json& v, Range range) const {
    if (!v.is_number()) fail(key, fmt::format("must be a number, not {}", v.type_name()));
    const double x = v.get<double>();
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
  e.thickness_m = s.number("Thickness [m]", kPositive);
  e.particle_radius_m = s.number("Particle radius [m]", kPositive);
  const double area_per_volume = s.number("Surface area per unit volume [m-1]", kPositive);
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
  e.max_concentration_mol_m3 = s.number("Maximum concentration [mol.m-3]", kPositive);
  e.conductivity_eff_s_m = s.number("Conductivity [S.m-1]", kPositive);

  // BPX: j0 = F k sqrt((c_e/c_e0) (c_s/c_max) (1 - c_s/c_max)), folded into the struct's
  // i0 = i0_coefficient sqrt(c_e c_s (c_max - c_s)).
  const double k_norm = s.number("Reaction rate constant [mol.m-2.s-1]", kPositive);
  e.i0_coefficient = kFaraday * k_norm / (std::sqrt(c_e0) * e.max_concentration_mol_m3);

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
      s.number_or("Diffusivity activation energy [J.mol-1]", kNonNegative, 0.0);
  e.rate_activation_j_mol =
      s.number_or("Reaction rate constant activation energy [J.mol-1]", kNonNegative, 0.0);

  // Our particle model has a constant diffusivity: a stoichiometry-dependent one is taken at
  // mid-range, x = 0.5.
  constexpr double kDiffusivityStoichiometry = 0.5;
  const ScalarFunctionPtr diffusivity = s.function("Diffusivity [m2.s-1]");
  s.check_function("Diffusivity [m2.s-1]", *diffusivity, kDiffusivityStoichiometry, kPositive);
  e.solid_diffusivity_m2_s = diffusivity->value(kDiffusivityStoichiometry);

  e.ocp_v = s.function("OCP [V]");
  e.entropic_v_k = s.function_or_null("Entropic change coefficient [V.K-1]");
  for (const double x : {e.stoich_min, 0.5 * (e.stoich_min + e.stoich_max), e.stoich_max}) {
    s.check_function("OCP [V]", *e.ocp_v, x, kOcp);
    if (e.entropic_v_k) {
      s.check_function("Entropic change coefficient [V.K-1]", *e.entropic_v_k, x, kAnyValue);
    }
  }
  return e;
}

}  // namespace

CellParameters read_bpx_text(std::string_view text, std::string_view name) {
  const std::string file(name);
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

  const double area = cell.number("Electrode area [m2]", kPositive);
  const std::string pairs_key = "Number of electrode pairs connected in parallel to make a cell";
  const double pairs = cell.number(pairs_key, {1.0, kInf, false, true});
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
  p.nominal_capacity_ah = cell.number("Nominal cell capacity [A.h]", kPositive);

  ThermalParameters& th = p.thermal;
  th.ambient_temperature_k = cell.number("Ambient temperature [K]", kTemperature);
  th.initial_temperature_k =
      cell.number_or("Initial temperature [K]", kTemperature, th.ambient_temperature_k);
  th.reference_temperature_k =
      cell.number_or("Reference temperature [K]", kTemperature, kDefaultReferenceTemperatureK);
  // Optional in BPX; 0 tells the thermal model they are unknown.
  th.specific_heat_j_kg_k = cell.number_or("Specific heat capacity [J.K-1.kg-1]", kPositive, 0.0);
  th.density_kg_m3 = cell.number_or("Density [kg.m-3]", kPositive, 0.0);
  th.volume_m3 = cell.number_or("Volume [m3]", kPositive, 0.0);
  th.external_area_m2 = cell.number_or("External surface area [m2]", kPositive, 0.0);

  ElectrolyteParameters& el = p.electrolyte;
  el.initial_concentration_mol_m3 =
      electrolyte.number("Initial concentration [mol.m-3]", kPositive);
  p.initial_electrolyte_mol_m3 = el.initial_concentration_mol_m3;
  el.transference_number = electrolyte.number("Cation transference number", kTransference);
  el.diffusivity_m2_s = electrolyte.function("Diffusivity [m2.s-1]");
  el.conductivity_s_m = electrolyte.function("Conductivity [S.m-1]");
  electrolyte.check_function("Diffusivity [m2.s-1]", *el.diffusivity_m2_s,
                             el.initial_concentration_mol_m3, kPositive);
  electrolyte.check_function("Conductivity [S.m-1]", *el.conductivity_s_m,
                             el.initial_concentration_mol_m3, kPositive);
  el.diffusivity_activation_j_mol =
      electrolyte.number_or("Diffusivity activation energy [J.mol-1]", kNonNegative, 0.0);
  el.conductivity_activation_j_mol =
      electrolyte.number_or("Conductivity activation energy [J.mol-1]", kNonNegative, 0.0);

  p.negative =
      read_electrode(params.section("Negative electrode"), el.initial_concentration_mol_m3, true);
  p.positive =
      read_electrode(params.section("Positive electrode"), el.initial_concentration_mol_m3, false);

  p.separator.thickness_m = separator.number("Thickness [m]", kPositive);
  p.separator.porosity = separator.number("Porosity", kOpenFraction);
  p.separator.transport_efficiency = separator.number("Transport efficiency", kTransportEfficiency);

  p.side.enabled = false;  // BPX has no side reaction
  return p;
}

CellParameters read_bpx(const std::filesystem::path& file) {
  return read_bpx_text(read_text_file(file), file.string());
}

}  // namespace bms
