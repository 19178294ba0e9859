#pragma once
// The firmware's cell as data: what the reduced model (bms/fw/model/reduced_cell.hpp) needs of a
// cell, built from any parameter set (a BPX file, the paper's), with its open-circuit
// potentials and electrolyte transport as Hermite tables (bms/fw/model/cell_table.hpp) and their
// largest errors against the source functions over the cell's operating range.
//
// One record, two uses (docs/architecture.md, "The cell as data"):
//  - build time: cell_header_text() writes it as a C++ traits struct with the field names of
//    PaperCellTraits (`bmssim cell-config --cell X --out DIR`), the way foxBMS 2 keeps a
//    per-project cell configuration; a cross build picks one with the CMake variable BMS_CELL;
//  - run time on the host: RuntimeCellTraits holds the same numbers for the calling thread, so
//    `bmssim estimate --cell FILE --model reduced` runs the same model on any file without a
//    compiler (a test holds the two identical for the templates).
#include <string>

#include "bms/fw/model/cell_table.hpp"
#include "bms/fw/model/model_bias_table.hpp"
#include "bms/fw/model/paper_cell.hpp"
#include "bms/fw/model/reduced_cell.hpp"
#include "cell/cell_parameters.hpp"

namespace bms {

// The reduced model's mesh for a cell other than the paper's: 16 shells in both particles (the
// paper's 2 cathode shells suit its 0.16 um LFP particles, not the 5-10 um particles of the
// LCO and NMC templates: with 2 the NMC template's design-time bias was 35 mV at 1C).
using AnyCellMesh = fw::ReducedMesh<3, 1, 3, 16, 16>;

inline constexpr int kOcpTableNodes = 1025;
inline constexpr int kElectrolyteTableNodes = 65;
using OcpTable = fw::HermiteTable<kOcpTableNodes>;
using ElectrolyteTable = fw::HermiteTable<kElectrolyteTableNodes>;

struct ReducedCellRecord {
  std::string name, source;
  double area_m2 = 0.0, temperature_k = 0.0, transference = 0.0, electrolyte_init_mol_m3 = 0.0;
  double separator_thickness_m = 0.0, separator_porosity = 0.0;
  double transport_efficiency_neg = 0.0, transport_efficiency_sep = 0.0, transport_efficiency_pos = 0.0;
  fw::paper::Electrode neg{}, pos{};
  double side_ref_potential_v = 0.0, side_exchange_a_m2 = 0.0, side_alpha = 0.0, initial_film_ohm_m2 = 0.0;
  double film_molar_mass_kg_mol = 0.0, film_density_kg_m3 = 0.0, film_conductivity_s_m = 0.0;
  double upper_voltage_v = 0.0, lower_voltage_v = 0.0, nominal_capacity_ah = 0.0;
  OcpTable ocp_neg{}, ocp_pos{};
  ElectrolyteTable diffusivity{}, conductivity{};
  // Largest errors of the tables against the source functions: OCPs over each electrode's
  // stoichiometry window (V), transport over 0.2-2.5 c_e0 (relative).
  double ocp_neg_max_err_v = 0.0, ocp_pos_max_err_v = 0.0;
  double diffusivity_max_rel_err = 0.0, conductivity_max_rel_err = 0.0;
  std::string notes;  // what the reduced model leaves out of this cell (thermodynamic factor, ...)
};

// InputError naming the cell and the field when the parameter set cannot become a record (a
// table that is not finite over its range, a missing side reaction).
ReducedCellRecord make_reduced_cell_record(const CellParameters& cell);

// The record as a generated C++ header: namespace bms::fw::cells, struct `type_name` with
// PaperCellTraits' fields, plus kModelBiasOhm and its state-of-charge tables: kModelBiasTable* at
// the nominal inventory, kModelBiasLean* / kModelBiasRich* kModelBiasInventoryStep below and above
// it (the design-time bias, computed by the caller; off: no table). The bias is a calibration of the
// model, not a number of the cell's record, but the firmware applies it to every tick: the
// header's CRC (kRecordCrc32) covers it with the record's numbers.
std::string cell_header_text(const ReducedCellRecord& r, const std::string& type_name, double model_bias_ohm,
                             const fw::ModelBiasTables<double>& model_bias_table);

// CRC-32 of the record's numbers (tables included) and of the design-time bias written with them
// (the constant, then each table's range, knots and trusted end, the nominal level first), written into the header as kRecordCrc32 and
// recomputed by the firmware at compile time (bms/fw/config/cell_choice.hpp: cell_config_crc32).
std::uint32_t record_crc32(const ReducedCellRecord& r, double model_bias_ohm,
                           const fw::ModelBiasTables<double>& model_bias_table);

// Host-only traits over the calling thread's record (set by RuntimeCellScope). The static
// members mirror PaperCellTraits; their values are those of the installed record.
struct RuntimeCellTraits {
  static thread_local double kAreaM2, kTemperatureK, kTransference, kElectrolyteInitMolM3;
  static thread_local double kSeparatorThicknessM, kSeparatorPorosity, kBruggeman;
  static thread_local double kTransportEfficiencyNeg, kTransportEfficiencySep, kTransportEfficiencyPos;
  static thread_local fw::paper::Electrode kNeg, kPos;
  static thread_local double kSideRefPotentialV, kSideExchangeAM2, kSideAlpha, kInitialFilmOhmM2;
  static thread_local double kFilmMolarMassKgMol, kFilmDensityKgM3, kFilmConductivitySM;
  static thread_local double kUpperVoltageV, kLowerVoltageV;
  static thread_local const ReducedCellRecord* record;
  // Isothermal data at the record's temperature (no activation energies, no entropic term): the
  // thermal voltage RT/F follows the measured temperature, the properties do not.
  struct Temperature : fw::IsothermalProperties {
    static thread_local double kReferenceK;
  };
  template <typename T> static T ocp_neg_v(T x) { return record->ocp_neg(x); }
  template <typename T> static T ocp_pos_v(T x) { return record->ocp_pos(x); }
  template <typename T> static T electrolyte_diffusivity_m2_s(T c) { return record->diffusivity(c); }
  template <typename T> static T electrolyte_conductivity_s_m(T c) { return record->conductivity(c); }
};

// Installs a record for this thread for the scope's life (the record must outlive it).
class RuntimeCellScope {
 public:
  explicit RuntimeCellScope(const ReducedCellRecord& r);
  ~RuntimeCellScope();
  RuntimeCellScope(const RuntimeCellScope&) = delete;
  RuntimeCellScope& operator=(const RuntimeCellScope&) = delete;

 private:
  const ReducedCellRecord* previous_;
};

}  // namespace bms
