#include "sim/truth_parameters.hpp"

#include <algorithm>
#include <cmath>
#include <memory>

#include <fmt/format.h>

#include "io/input_error.hpp"

namespace bms {
namespace {

// Inventory root find: stoichiometries closer to 0 or 1 than this are not accepted, since the
// open-circuit-potential fits diverge at the edges (1/x and log terms) and such a cell could not
// be cycled anyway.
constexpr double kStoichLimitLow = 1e-3;
constexpr double kStoichLimitHigh = 1.0 - 1e-3;

struct Entry {
  TruthParameter info;
  double (*nominal)(const CellParameters&);
  void (*apply)(CellParameters&, double);
};

double factor_nominal(const CellParameters&) { return 1.0; }

// Without a side reaction the truth starts from no film (default_initial_conditions).
double film_nominal_ohm_m2(const CellParameters& c) {
  return c.side.enabled ? c.side.initial_film_resistance_ohm_m2 : 0.0;
}

ScalarFunctionPtr scaled(const ScalarFunctionPtr& f, double factor) {
  return std::make_shared<ScaledFunction>(f, factor);
}

// Every apply changes only the cell; run_simulation builds the truth from it as from any cell.
// The initial film is the one exception: the initial conditions zero it on a cell without a
// side reaction, so run_simulation takes it from TruthSettings::value (there it is a constant
// series resistance in the anode's overpotential, which the DFN keeps with the reaction off).
const std::vector<Entry>& entries() {
  static const std::vector<Entry> table = {
      {{"r_film_initial_ohm_m2", "ohm_m2", 0.0, 1.0, false, false, "film resistance at t = 0"},
       film_nominal_ohm_m2,
       [](CellParameters& c, double v) { c.side.initial_film_resistance_ohm_m2 = v; }},
      // > 0: the lithium loss is read back from the film through this factor.
      {{"film_growth_scale", "-", 0.0, 100.0, true, true,
        "factor on the film-growth law dR_film/dt (not on the lithium the side reaction consumes)"},
       factor_nominal,
       [](CellParameters& c, double v) { c.side.film_growth_scale = v; }},
      {{"side_i0_scale", "-", 0.0, 100.0, true, true, "factor on the side reaction's exchange current density"},
       factor_nominal,
       [](CellParameters& c, double v) { c.side.exchange_current_a_m2 *= v; }},
      {{"inventory_scale", "-", 0.8, 1.2, false, false,
        "factor on the cyclable lithium at t = 0 (the cell at rest in equilibrium, same open-circuit voltage)"},
       factor_nominal,
       [](CellParameters& c, double v) { scale_initial_inventory(c, v); }},
      {{"temperature_k", "K", 233.15, 353.15, false, false, "ambient and initial temperature"},
       [](const CellParameters& c) { return c.thermal.ambient_temperature_k; },
       [](CellParameters& c, double v) { c.thermal.ambient_temperature_k = c.thermal.initial_temperature_k = v; }},
      {{"conductivity_scale", "-", 0.0, 10.0, true, false, "factor on the electrolyte conductivity kappa(c_e)"},
       factor_nominal,
       [](CellParameters& c, double v) { c.electrolyte.conductivity_s_m = scaled(c.electrolyte.conductivity_s_m, v); }},
      {{"electrolyte_diffusivity_scale", "-", 0.0, 10.0, true, false,
        "factor on the electrolyte diffusivity D_e(c_e)"},
       factor_nominal,
       [](CellParameters& c, double v) { c.electrolyte.diffusivity_m2_s = scaled(c.electrolyte.diffusivity_m2_s, v); }},
      {{"diffusivity_scale_negative", "-", 0.0, 10.0, true, false, "factor on the anode's solid diffusivity"},
       factor_nominal,
       [](CellParameters& c, double v) { c.negative.solid_diffusivity_m2_s *= v; }},
      {{"diffusivity_scale_positive", "-", 0.0, 10.0, true, false, "factor on the cathode's solid diffusivity"},
       factor_nominal,
       [](CellParameters& c, double v) { c.positive.solid_diffusivity_m2_s *= v; }},
      {{"i0_scale_negative", "-", 0.0, 100.0, true, false,
        "factor on the anode's intercalation exchange current density"},
       factor_nominal,
       [](CellParameters& c, double v) { c.negative.i0_coefficient *= v; }},
      {{"i0_scale_positive", "-", 0.0, 100.0, true, false,
        "factor on the cathode's intercalation exchange current density"},
       factor_nominal,
       [](CellParameters& c, double v) { c.positive.i0_coefficient *= v; }},
      // Cell-to-cell capacity spread: the same design with a little more or less electrode.
      {{"electrode_area_scale", "-", 0.5, 2.0, false, false,
        "factor on the electrode area: both electrodes' capacity, and every current density at a given current"},
       factor_nominal,
       [](CellParameters& c, double v) { c.electrode_area_m2 *= v; }},
  };
  return table;
}

const Entry* find_entry(std::string_view name) {
  for (const Entry& e : entries())
    if (name == e.info.name) return &e;
  return nullptr;
}

std::string known_names() {
  std::string s;
  for (const Entry& e : entries()) s += (s.empty() ? "" : ", ") + std::string(e.info.name);
  return s;
}

bool in_range(const TruthParameter& p, double v) {
  return (p.min_excluded ? v > p.min_value : v >= p.min_value) && v <= p.max_value;
}

double parse_number(const std::string& text, const std::string& assignment) {
  double v = 0.0;
  try {
    size_t used = 0;
    v = std::stod(text, &used);
    if (used != text.size()) throw std::invalid_argument("trailing characters");
  } catch (const std::exception&) {
    throw InputError("--set '" + assignment + "': VALUE must be a number");
  }
  return v;
}

}  // namespace

const std::vector<TruthParameter>& truth_parameters() {
  static const std::vector<TruthParameter> list = [] {
    std::vector<TruthParameter> out;
    for (const Entry& e : entries()) out.push_back(e.info);
    return out;
  }();
  return list;
}

std::string range_text(const TruthParameter& p) {
  return fmt::format("{}{:g}, {:g}]", p.min_excluded ? "(" : "[", p.min_value, p.max_value);
}

double nominal_truth_value(const CellParameters& cell, std::string_view name) {
  const Entry* e = find_entry(name);
  if (!e) throw InputError("--set " + std::string(name) + ": unknown parameter; use one of " + known_names());
  return e->nominal(cell);
}

std::string truth_parameter_listing(const CellParameters& cell) {
  std::string out =
      fmt::format("# --set NAME=VALUE for cell '{}': name, nominal value, unit, range, meaning\n", cell.name);
  for (const Entry& e : entries()) {
    std::string meaning = e.info.meaning;
    if (e.info.needs_side_reaction && !cell.side.enabled) meaning += " (not for this cell: it has no side reaction)";
    out += fmt::format("{:<30} {:<12.10g} {:<7} {:<16} {}\n", e.info.name, e.nominal(cell), e.info.unit,
                       range_text(e.info), meaning);
  }
  return out;
}

TruthSettings TruthSettings::parse(const std::vector<std::string>& assignments) {
  TruthSettings s;
  for (const std::string& a : assignments) {
    const auto eq = a.find('=');
    if (eq == std::string::npos || eq == 0) throw InputError("--set '" + a + "': expected NAME=VALUE");
    const std::string name = a.substr(0, eq);
    const Entry* e = find_entry(name);
    if (!e) throw InputError("--set '" + name + "': unknown parameter; use one of " + known_names());
    const double v = parse_number(a.substr(eq + 1), a);
    if (!std::isfinite(v))
      throw InputError("--set " + name + ": VALUE must be a finite number in " + range_text(e->info));
    if (!in_range(e->info, v))
      throw InputError(fmt::format("--set {}={:g}: outside its range {}{}", name, v, range_text(e->info),
                                   std::string_view(e->info.unit) == "-" ? "" : " " + std::string(e->info.unit)));
    if (!s.values_.emplace(name, v).second) throw InputError("--set " + name + ": given twice");
  }
  return s;
}

double TruthSettings::value(const CellParameters& nominal, std::string_view name) const {
  const auto it = values_.find(name);
  return it != values_.end() ? it->second : nominal_truth_value(nominal, name);
}

CellParameters TruthSettings::apply(const CellParameters& nominal) const {
  CellParameters cell = nominal;
  for (const Entry& e : entries()) {  // table order, whatever the order on the command line
    const auto it = values_.find(e.info.name);
    if (it == values_.end()) continue;
    if (e.info.needs_side_reaction && !nominal.side.enabled)
      throw InputError(fmt::format("--set {}: cell '{}' has its side reaction switched off, so there is "
                                   "nothing to scale",
                                   e.info.name, nominal.name));
    e.apply(cell, it->second);
  }
  return cell;
}

nlohmann::json TruthSettings::values_json(const CellParameters& nominal) const {
  nlohmann::json j = nlohmann::json::object();
  for (const Entry& e : entries()) j[e.info.name] = value(nominal, e.info.name);
  return j;
}

void scale_initial_inventory(CellParameters& cell, double inventory_scale) {
  // 1 is the nominal cell itself: no root find, so it reproduces the nominal state exactly.
  if (inventory_scale == 1.0) return;
  const ElectrodeParameters& neg = cell.negative;
  const ElectrodeParameters& pos = cell.positive;
  // Solid lithium per electrode area and unit of stoichiometry (mol/m2).
  const double q_neg_mol_m2 = neg.thickness_m * neg.solid_fraction * neg.max_concentration_mol_m3;
  const double q_pos_mol_m2 = pos.thickness_m * pos.solid_fraction * pos.max_concentration_mol_m3;
  const double x0 = neg.stoich_init, y0 = pos.stoich_init;
  const double ocv_v = pos.ocp_v->value(y0) - neg.ocp_v->value(x0);
  const double target_mol_m2 = inventory_scale * (q_neg_mol_m2 * x0 + q_pos_mol_m2 * y0);
  // The cathode takes whatever lithium the anode does not: the total is exact for any x.
  const auto stoich_pos = [&](double x) { return (target_mol_m2 - q_neg_mol_m2 * x) / q_pos_mol_m2; };
  // Rises with x for OCPs that fall with lithiation: one root at most.
  const auto ocv_gap_v = [&](double x) { return pos.ocp_v->value(stoich_pos(x)) - neg.ocp_v->value(x) - ocv_v; };

  double lo = std::max(kStoichLimitLow, (target_mol_m2 - q_pos_mol_m2 * kStoichLimitHigh) / q_neg_mol_m2);
  double hi = std::min(kStoichLimitHigh, (target_mol_m2 - q_pos_mol_m2 * kStoichLimitLow) / q_neg_mol_m2);
  const auto none = [&] {
    return InputError(fmt::format("--set inventory_scale={:g}: cell '{}' has no state at rest with the initial "
                                  "open-circuit voltage {:.4f} V and {:g} times its lithium within the "
                                  "stoichiometry limits [{:g}, {:g}]",
                                  inventory_scale, cell.name, ocv_v, inventory_scale, kStoichLimitLow,
                                  kStoichLimitHigh));
  };
  if (!(lo < hi)) throw none();
  double gap_lo = ocv_gap_v(lo);
  const double gap_hi = ocv_gap_v(hi);
  if (!(std::isfinite(gap_lo) && std::isfinite(gap_hi)) || (gap_lo > 0.0) == (gap_hi > 0.0)) throw none();
  // Bisection to the last bit: 200 halvings exceed any double interval in (0, 1).
  for (int i = 0; i < 200; ++i) {
    const double mid = 0.5 * (lo + hi);
    if (mid <= lo || mid >= hi) break;  // lo and hi are neighbouring doubles
    const double gap_mid = ocv_gap_v(mid);
    if ((gap_mid > 0.0) == (gap_lo > 0.0)) {
      lo = mid;
      gap_lo = gap_mid;
    } else {
      hi = mid;
    }
  }
  const double x = 0.5 * (lo + hi);
  cell.negative.stoich_init = x;
  cell.positive.stoich_init = stoich_pos(x);
}

}  // namespace bms
