#include "cell/reduced_cell_record.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <filesystem>
#include <vector>

#include "io/input_error.hpp"

namespace bms {
namespace {

// OCP tables span the stoichiometry window widened by this share of its width on each side
// (a surface under current leaves the window), inside (kEdge, 1 - kEdge) where fits diverge.
constexpr double kOcpWidening = 0.1;
constexpr double kOcpEdge = 2e-3;
// Electrolyte tables span kElectrolyteLow..kElectrolyteHigh times c_e0; errors are stated
// over kErrLow..kErrHigh times c_e0 (what a cell visits up to about 2C).
constexpr double kElectrolyteLow = 0.02, kElectrolyteHigh = 4.0;
constexpr double kErrLow = 0.2, kErrHigh = 2.5;
constexpr int kErrSamplesPerStep = 16;

template <int N>
fw::HermiteTable<N> tabulate(const ScalarFunction& f, double x0, double x1, const std::string& where) {
  fw::HermiteTable<N> t{};
  t.x_first = x0;
  t.x_last = x1;
  for (int i = 0; i < N; ++i) {
    const double x = x0 + (x1 - x0) * i / (N - 1);
    f.value_and_derivative(x, t.y[i], t.dydx[i]);
    if (!std::isfinite(t.y[i]) || !std::isfinite(t.dydx[i]))
      throw InputError(fmt::format("{}: not finite at x = {} (value {}, derivative {}); the firmware's table spans "
                                   "[{}, {}]",
                                   where, x, t.y[i], t.dydx[i], x0, x1));
  }
  return t;
}

// Largest |table - f| (absolute, or relative to |f|) over [a, b].
template <int N>
double max_error(const fw::HermiteTable<N>& t, const ScalarFunction& f, double a, double b, bool relative) {
  const int samples = (N - 1) * kErrSamplesPerStep;
  double worst = 0.0;
  for (int k = 0; k <= samples; ++k) {
    const double x = a + (b - a) * k / samples;
    const double exact = f.value(x);
    double e = std::abs(t(x) - exact);
    if (relative) e /= std::abs(exact);
    worst = std::max(worst, e);
  }
  return worst;
}

fw::paper::Electrode electrode_of(const ElectrodeParameters& e) {
  return {e.thickness_m,          e.particle_radius_m,       e.solid_fraction,
          e.porosity,             e.solid_diffusivity_m2_s,  e.max_concentration_mol_m3,
          e.conductivity_eff_s_m, e.i0_coefficient,          e.stoich_init};
}

OcpTable ocp_table(const ElectrodeParameters& e, const std::string& where, double& max_err_v) {
  const double width = e.stoich_max - e.stoich_min;
  const double lo = std::max(kOcpEdge, e.stoich_min - kOcpWidening * width);
  const double hi = std::min(1.0 - kOcpEdge, e.stoich_max + kOcpWidening * width);
  const OcpTable t = tabulate<kOcpTableNodes>(*e.ocp_v, lo, hi, where);
  max_err_v = max_error(t, *e.ocp_v, std::max(lo, e.stoich_min), std::min(hi, e.stoich_max), false);
  return t;
}

}  // namespace

ReducedCellRecord make_reduced_cell_record(const CellParameters& c) {
  const std::string where = c.source.empty() ? c.name : c.source;
  if (!c.side.enabled)
    throw InputError(fmt::format("{}: the firmware's model needs the cell's side reaction (switched off)", where));
  ReducedCellRecord r;
  r.name = c.name;
  r.source = c.source;
  r.area_m2 = c.electrode_area_m2;
  r.temperature_k = c.thermal.ambient_temperature_k;
  r.transference = c.electrolyte.transference_number;
  r.electrolyte_init_mol_m3 = c.electrolyte.initial_concentration_mol_m3;
  r.separator_thickness_m = c.separator.thickness_m;
  r.separator_porosity = c.separator.porosity;
  r.transport_efficiency_neg = c.negative.transport_efficiency;
  r.transport_efficiency_sep = c.separator.transport_efficiency;
  r.transport_efficiency_pos = c.positive.transport_efficiency;
  r.neg = electrode_of(c.negative);
  r.pos = electrode_of(c.positive);
  r.side_ref_potential_v = c.side.reference_potential_v;
  r.side_exchange_a_m2 = c.side.exchange_current_a_m2;
  r.side_alpha = c.side.transfer_coefficient;
  r.initial_film_ohm_m2 = c.side.initial_film_resistance_ohm_m2;
  r.film_molar_mass_kg_mol = c.side.molar_mass_kg_mol;
  r.film_density_kg_m3 = c.side.density_kg_m3;
  r.film_conductivity_s_m = c.side.film_conductivity_s_m;
  r.upper_voltage_v = c.upper_voltage_v;
  r.lower_voltage_v = c.lower_voltage_v;
  r.nominal_capacity_ah = c.nominal_capacity_ah;
  r.ocp_neg = ocp_table(c.negative, where + ": field 'Negative electrode.OCP [V]'", r.ocp_neg_max_err_v);
  r.ocp_pos = ocp_table(c.positive, where + ": field 'Positive electrode.OCP [V]'", r.ocp_pos_max_err_v);
  const double c0 = r.electrolyte_init_mol_m3;
  r.diffusivity = tabulate<kElectrolyteTableNodes>(*c.electrolyte.diffusivity_m2_s, kElectrolyteLow * c0,
                                                   kElectrolyteHigh * c0,
                                                   where + ": field 'Electrolyte.Diffusivity [m2.s-1]'");
  r.conductivity = tabulate<kElectrolyteTableNodes>(*c.electrolyte.conductivity_s_m, kElectrolyteLow * c0,
                                                    kElectrolyteHigh * c0,
                                                    where + ": field 'Electrolyte.Conductivity [S.m-1]'");
  r.diffusivity_max_rel_err = max_error(r.diffusivity, *c.electrolyte.diffusivity_m2_s, kErrLow * c0, kErrHigh * c0, true);
  r.conductivity_max_rel_err =
      max_error(r.conductivity, *c.electrolyte.conductivity_s_m, kErrLow * c0, kErrHigh * c0, true);
  if (c.electrolyte.thermodynamic_factor)
    r.notes += "the electrolyte's thermodynamic factor is taken as 1 (an ideal solution, as the paper's model); ";
  if (c.negative.diffusivity_activation_j_mol > 0.0 || c.positive.diffusivity_activation_j_mol > 0.0 ||
      c.negative.rate_activation_j_mol > 0.0 || c.positive.rate_activation_j_mol > 0.0)
    r.notes += "activation energies are not used (isothermal at the cell's ambient temperature); ";
  if (c.negative.entropic_v_k || c.positive.entropic_v_k) r.notes += "entropic coefficients are not used; ";
  // The cell's own effects (BPX User-defined keys) are the truth model's, not the reduced model's.
  const CellEffectParameters& fx = c.effects;
  if (fx.contact_resistance_ohm > 0.0)
    r.notes += fmt::format("the contact resistance ({:.4g} ohm) is not in this record (`estimate` adds it as a model "
                           "effect; a board image built from the record does not have it); ",
                           fx.contact_resistance_ohm);
  if (fx.hysteresis_v > 0.0)
    r.notes += fmt::format("the OCP hysteresis ({:.4g} V) is not in this record (`estimate` adds it as a model "
                           "effect; a board image does not); ",
                           fx.hysteresis_v);
  if (fx.thermal_h_w_per_k > 0.0) r.notes += "the lumped thermal model is not used (isothermal); ";
  if (fx.particle_size_sigma > 0.0) r.notes += "the positive particle-size spread is not used (one size); ";
  if (fx.diffusivity_profile_positive != 0.0 || c.positive.solid_diffusivity_factor || c.negative.solid_diffusivity_factor)
    r.notes += "the solid diffusivities are constant (their values at x = 0.5; the dependence on stoichiometry is the "
               "truth model's only); ";
  if (fx.resistive_reactant_positive_ohm_m2 > 0.0)
    r.notes += "the cathode's resistive reactant is not used (the truth model's only); ";
  return r;
}

namespace {

class Crc32 {
 public:
  void add(const void* data, std::size_t n) {
    const auto* p = static_cast<const unsigned char*>(data);
    for (std::size_t i = 0; i < n; ++i) {
      crc_ ^= p[i];
      for (int k = 0; k < 8; ++k) crc_ = (crc_ >> 1) ^ (0xEDB88320u & (0u - (crc_ & 1u)));
    }
  }
  void add(double v) { add(&v, sizeof v); }
  template <int N>
  void add(const fw::HermiteTable<N>& t) {
    add(t.x_first);
    add(t.x_last);
    for (int i = 0; i < N; ++i) {
      add(t.y[i]);
      add(t.dydx[i]);
    }
  }
  void add(const fw::paper::Electrode& e) {
    for (double v : {e.thickness_m, e.particle_radius_m, e.solid_fraction, e.porosity, e.solid_diffusivity_m2_s,
                     e.max_concentration_mol_m3, e.conductivity_eff_s_m, e.i0_coefficient, e.stoich_init})
      add(v);
  }
  std::uint32_t value() const { return ~crc_; }

 private:
  std::uint32_t crc_ = 0xFFFFFFFFu;
};

// Round-trip precision, and always a floating literal (a whole number gets ".0": an integer
// literal of 17 digits would be a narrowing conversion to double).
std::string num(double v) {
  std::string s = fmt::format("{:.17g}", v);
  if (s.find_first_of(".eEn") == std::string::npos) s += ".0";
  return s;
}

std::string electrode_text(const fw::paper::Electrode& e) {
  return fmt::format("{{{}, {}, {}, {}, {}, {}, {}, {}, {}}}", num(e.thickness_m), num(e.particle_radius_m),
                     num(e.solid_fraction), num(e.porosity), num(e.solid_diffusivity_m2_s),
                     num(e.max_concentration_mol_m3), num(e.conductivity_eff_s_m), num(e.i0_coefficient),
                     num(e.stoich_init));
}

template <int N>
std::string table_text(const fw::HermiteTable<N>& t) {
  std::string y, d;
  for (int i = 0; i < N; ++i) {
    y += (i ? (i % 4 ? ", " : ",\n      ") : "") + num(t.y[i]);
    d += (i ? (i % 4 ? ", " : ",\n      ") : "") + num(t.dydx[i]);
  }
  return fmt::format("{{{}, {},\n     {{{}}},\n     {{{}}}}}", num(t.x_first), num(t.x_last), y, d);
}

// The trusted span's end as the header holds it: 0 for none (+inf in the table).
double trusted_last_in_header(double x) { return std::isfinite(x) ? x : 0.0; }

}  // namespace

std::uint32_t record_crc32(const ReducedCellRecord& r, double model_bias_ohm,
                           const fw::ModelBiasTables<double>& model_bias_table) {
  Crc32 c;
  for (double v : {r.area_m2, r.temperature_k, r.transference, r.electrolyte_init_mol_m3, r.separator_thickness_m,
                   r.separator_porosity, r.transport_efficiency_neg, r.transport_efficiency_sep,
                   r.transport_efficiency_pos, r.side_ref_potential_v, r.side_exchange_a_m2, r.side_alpha,
                   r.initial_film_ohm_m2, r.film_molar_mass_kg_mol, r.film_density_kg_m3, r.film_conductivity_s_m,
                   r.upper_voltage_v, r.lower_voltage_v, r.nominal_capacity_ah})
    c.add(v);
  c.add(r.neg);
  c.add(r.pos);
  c.add(r.ocp_neg);
  c.add(r.ocp_pos);
  c.add(r.diffusivity);
  c.add(r.conductivity);
  c.add(model_bias_ohm);
  const auto add_level = [&](const fw::ModelBiasTable<double>& t) {
    c.add(t.x_first);
    c.add(t.x_last);
    for (double v : t.ohm) c.add(v);
    c.add(trusted_last_in_header(t.x_trusted_last));
  };
  add_level(model_bias_table.level[1]);
  c.add(model_bias_table.nu_step);
  add_level(model_bias_table.level[0]);
  add_level(model_bias_table.level[2]);
  c.add(model_bias_table.covered_charge_a_min);
  c.add(model_bias_table.constant_alone_covered ? 1.0 : 0.0);
  return c.value();
}

std::string cell_header_text(const ReducedCellRecord& r, const std::string& type_name, double model_bias_ohm,
                             const fw::ModelBiasTables<double>& model_bias_table) {
  static_assert(fw::kModelBiasLevels == 3, "the header holds three levels: lean, nominal, rich");
  std::string s = fmt::format(
      "#pragma once\n"
      "// Generated by `bmssim cell-config --cell {name}` from {source}: the firmware's cell\n"
      "// configuration (host_sim/src/cell/reduced_cell_record.hpp). Do not edit; regenerate.\n"
      "// Table errors against the source functions: OCP negative {en:.3g} V, positive {ep:.3g} V over the\n"
      "// stoichiometry windows; electrolyte diffusivity {ed:.3g}, conductivity {ek:.3g} (relative) over\n"
      "// 0.2-2.5 c_e0.{notes}\n"
      "#include <cstdint>\n\n#include \"bms/fw/model/cell_table.hpp\"\n#include \"bms/fw/model/paper_cell.hpp\"\n\n"
      "namespace bms::fw::cells {{\n\n"
      "static_assert(kCellConfigSchema == 3, \"generated for cell configuration schema 3: regenerate\");\n\n"
      "struct {type} {{\n",
      fmt::arg("name", r.name), fmt::arg("source", std::filesystem::path(r.source).filename().string()), fmt::arg("en", r.ocp_neg_max_err_v),
      fmt::arg("ep", r.ocp_pos_max_err_v), fmt::arg("ed", r.diffusivity_max_rel_err),
      fmt::arg("ek", r.conductivity_max_rel_err),
      fmt::arg("notes", r.notes.empty() ? "" : "\n// Left out by the reduced model: " + r.notes),
      fmt::arg("type", type_name));
  const auto field = [&](const char* n, double v) { s += fmt::format("  static constexpr double {} = {};\n", n, num(v)); };
  field("kAreaM2", r.area_m2);
  field("kTemperatureK", r.temperature_k);
  field("kTransference", r.transference);
  field("kElectrolyteInitMolM3", r.electrolyte_init_mol_m3);
  field("kSeparatorThicknessM", r.separator_thickness_m);
  field("kSeparatorPorosity", r.separator_porosity);
  s += "  static constexpr double kBruggeman = 0.0;  // unused: the regions' transport efficiencies below\n";
  field("kTransportEfficiencyNeg", r.transport_efficiency_neg);
  field("kTransportEfficiencySep", r.transport_efficiency_sep);
  field("kTransportEfficiencyPos", r.transport_efficiency_pos);
  s += "  static constexpr paper::Electrode kNeg" + electrode_text(r.neg) + ";\n";
  s += "  static constexpr paper::Electrode kPos" + electrode_text(r.pos) + ";\n";
  field("kSideRefPotentialV", r.side_ref_potential_v);
  field("kSideExchangeAM2", r.side_exchange_a_m2);
  field("kSideAlpha", r.side_alpha);
  field("kInitialFilmOhmM2", r.initial_film_ohm_m2);
  field("kFilmMolarMassKgMol", r.film_molar_mass_kg_mol);
  field("kFilmDensityKgM3", r.film_density_kg_m3);
  field("kFilmConductivitySM", r.film_conductivity_s_m);
  field("kUpperVoltageV", r.upper_voltage_v);
  field("kLowerVoltageV", r.lower_voltage_v);
  field("kNominalCapacityAh", r.nominal_capacity_ah);
  field("kModelBiasOhm", model_bias_ohm);
  const auto level = [&](const std::string& prefix, const fw::ModelBiasTable<double>& t) {
    field((prefix + "First").c_str(), t.x_first);
    field((prefix + "Last").c_str(), t.x_last);
    s += fmt::format("  static constexpr double {}Ohm[{}] = {{\n     ", prefix, fw::ModelBiasTable<double>::kKnots);
    for (int k = 0; k < fw::ModelBiasTable<double>::kKnots; ++k)
      s += (k == 0 ? " " : k % 4 == 0 ? ",\n      " : ", ") + num(t.ohm[k]);
    s += "};\n";
    field((prefix + "TrustedLast").c_str(), trusted_last_in_header(t.x_trusted_last));
  };
  s += "  // The bias's state-of-charge part at the nominal inventory (bms/fw/model/model_bias_table.hpp;\n"
       "  // first = last: none); past TrustedLast (mean anode stoichiometry) a CC charge's learning stops\n"
       "  // (the model leaves the nominal cell; 0: none)\n";
  level("kModelBiasTable", model_bias_table.level[1]);
  s += "  // The same at the inventory kModelBiasInventoryStep below (Lean) and above (Rich) nominal (0: the nominal level alone)\n";
  field("kModelBiasInventoryStep", model_bias_table.nu_step);
  level("kModelBiasLean", model_bias_table.level[0]);
  level("kModelBiasRich", model_bias_table.level[2]);
  s += "  // The calibration's coverage: a CC charge below this current [A], or one on the constant alone\n"
       "  // (begun above the table's start margin) where ConstantAloneCovered is 0, is not learned from\n";
  field("kModelBiasCoveredChargeA", model_bias_table.covered_charge_a_min);
  field("kModelBiasConstantAloneCovered", model_bias_table.constant_alone_covered ? 1.0 : 0.0);
  s += fmt::format("  static constexpr std::uint32_t kRecordCrc32 = 0x{:08X}u;\n", record_crc32(r, model_bias_ohm, model_bias_table));
  s += fmt::format("  static constexpr HermiteTable<{}> kOcpNeg{};\n", kOcpTableNodes, table_text(r.ocp_neg));
  s += fmt::format("  static constexpr HermiteTable<{}> kOcpPos{};\n", kOcpTableNodes, table_text(r.ocp_pos));
  s += fmt::format("  static constexpr HermiteTable<{}> kDiffusivity{};\n", kElectrolyteTableNodes,
                   table_text(r.diffusivity));
  s += fmt::format("  static constexpr HermiteTable<{}> kConductivity{};\n", kElectrolyteTableNodes,
                   table_text(r.conductivity));
  s += "  template <typename T> static T ocp_neg_v(T x) { return kOcpNeg(x); }\n"
       "  template <typename T> static T ocp_pos_v(T x) { return kOcpPos(x); }\n"
       "  template <typename T> static T electrolyte_diffusivity_m2_s(T c) { return kDiffusivity(c); }\n"
       "  template <typename T> static T electrolyte_conductivity_s_m(T c) { return kConductivity(c); }\n"
       "};\n\n}  // namespace bms::fw::cells\n";
  return s;
}

thread_local double RuntimeCellTraits::kAreaM2, RuntimeCellTraits::kTemperatureK, RuntimeCellTraits::kTransference,
    RuntimeCellTraits::kElectrolyteInitMolM3;
thread_local double RuntimeCellTraits::kSeparatorThicknessM, RuntimeCellTraits::kSeparatorPorosity,
    RuntimeCellTraits::kBruggeman;
thread_local double RuntimeCellTraits::kTransportEfficiencyNeg, RuntimeCellTraits::kTransportEfficiencySep,
    RuntimeCellTraits::kTransportEfficiencyPos;
thread_local fw::paper::Electrode RuntimeCellTraits::kNeg, RuntimeCellTraits::kPos;
thread_local double RuntimeCellTraits::kSideRefPotentialV, RuntimeCellTraits::kSideExchangeAM2,
    RuntimeCellTraits::kSideAlpha, RuntimeCellTraits::kInitialFilmOhmM2;
thread_local double RuntimeCellTraits::kFilmMolarMassKgMol, RuntimeCellTraits::kFilmDensityKgM3,
    RuntimeCellTraits::kFilmConductivitySM;
thread_local double RuntimeCellTraits::kUpperVoltageV, RuntimeCellTraits::kLowerVoltageV;
thread_local const ReducedCellRecord* RuntimeCellTraits::record = nullptr;
thread_local double RuntimeCellTraits::Temperature::kReferenceK;

namespace {

void install(const ReducedCellRecord& r) {
  using T = RuntimeCellTraits;
  T::kAreaM2 = r.area_m2;
  T::kTemperatureK = r.temperature_k;
  T::Temperature::kReferenceK = r.temperature_k;
  T::kTransference = r.transference;
  T::kElectrolyteInitMolM3 = r.electrolyte_init_mol_m3;
  T::kSeparatorThicknessM = r.separator_thickness_m;
  T::kSeparatorPorosity = r.separator_porosity;
  T::kBruggeman = 0.0;
  T::kTransportEfficiencyNeg = r.transport_efficiency_neg;
  T::kTransportEfficiencySep = r.transport_efficiency_sep;
  T::kTransportEfficiencyPos = r.transport_efficiency_pos;
  T::kNeg = r.neg;
  T::kPos = r.pos;
  T::kSideRefPotentialV = r.side_ref_potential_v;
  T::kSideExchangeAM2 = r.side_exchange_a_m2;
  T::kSideAlpha = r.side_alpha;
  T::kInitialFilmOhmM2 = r.initial_film_ohm_m2;
  T::kFilmMolarMassKgMol = r.film_molar_mass_kg_mol;
  T::kFilmDensityKgM3 = r.film_density_kg_m3;
  T::kFilmConductivitySM = r.film_conductivity_s_m;
  T::kUpperVoltageV = r.upper_voltage_v;
  T::kLowerVoltageV = r.lower_voltage_v;
  T::record = &r;
}

}  // namespace

RuntimeCellScope::RuntimeCellScope(const ReducedCellRecord& r) : previous_(RuntimeCellTraits::record) { install(r); }

RuntimeCellScope::~RuntimeCellScope() {
  if (previous_ != nullptr) {
    install(*previous_);
  } else {
    RuntimeCellTraits::record = nullptr;
  }
}

}  // namespace bms
