#pragma once
// The cell a firmware build holds, chosen at build time: the CMake cache variable BMS_CELL
// (paper, lco, nmc, aboutenergy) becomes BMS_CELL_ID, and the build's images (bms-firmware,
// the board images of target/) take SelectedCell. One configuration per build, as foxBMS 2
// keeps one battery-cell configuration per project: the cell's numbers are constants in flash,
// the model's code is specialised on them, nothing is read or checked per tick.
//
// A generated configuration (bms/fw/cells/*_cell.hpp, `bmssim cell-config`) states the schema
// it was written for (a static_assert in the header) and the CRC-32 of its numbers
// (kRecordCrc32), the design-time bias (kModelBiasOhm, kModelBiasTable*, its inventory levels
// kModelBiasLean*, kModelBiasRich*, kModelBiasInventoryStep) included; GeneratedCell
// recomputes that CRC at compile time from the numbers the header holds, so an edited or damaged
// header does not compile. The state a model of that
// cell saves to NVM is tagged with the same CRC (nvm/state_schema.hpp: CellIdentity), so a
// state saved under one cell is refused under another.
// Firmware rules: constexpr only, no heap.
#include <cstdint>
#include <type_traits>

#include "bms/fw/cells/aboutenergy_cell.hpp"
#include "bms/fw/cells/lco_cell.hpp"
#include "bms/fw/cells/nmc_cell.hpp"
#include "bms/fw/config/make_config.hpp"
#include "bms/fw/model/cell_table.hpp"
#include "bms/fw/model/model_bias_table.hpp"
#include "bms/fw/model/reduced_cell.hpp"
#include "bms/fw/model/reduced_model_bias.hpp"
#if defined(BMS_CELL_ID) && BMS_CELL_ID == 4
// A cell given as a BPX file (CMake BMS_CELL_FILE): the build wrote this header with `bmssim
// cell-config` (target/tools/cell_file.cmake); it defines cells::FileCellTraits and FileCellName.
#include "bms/fw/cells/file_cell.hpp"
#endif

namespace bms::fw {

namespace cell_crc {

/// IEEE 754 binary64 bits of a finite double, by arithmetic (C++17 has no constexpr bit_cast):
/// scaling by two is exact, so the exponent and the 52-bit fraction come out exactly.
/// (-0.0 reads as +0.0: a header holding -0.0 would fail its CRC, loudly.)
constexpr std::uint64_t double_bits(double v) {
  if (v == 0.0) return 0;
  const std::uint64_t sign = v < 0.0 ? (std::uint64_t{1} << 63) : 0;
  double a = v < 0.0 ? -v : v;
  int e = 0;
  while (a >= 2.0) {
    a /= 2.0;
    ++e;
  }
  while (a < 1.0 && e > -1022) {
    a *= 2.0;
    --e;
  }
  constexpr double kTwo52 = 4503599627370496.0;
  if (a < 1.0) return sign | static_cast<std::uint64_t>(a * kTwo52);  // subnormal: exponent field 0
  const std::uint64_t fraction = static_cast<std::uint64_t>((a - 1.0) * kTwo52);
  return sign | (static_cast<std::uint64_t>(e + 1023) << 52) | fraction;
}

/// The byte table of CRC-32 (IEEE, reflected), built at compile time.
struct Table {
  std::uint32_t entry[256];
};
constexpr Table make_table() {
  Table t{};
  for (std::uint32_t b = 0; b < 256; ++b) {
    std::uint32_t c = b;
    for (int k = 0; k < 8; ++k) c = (c >> 1) ^ (0xEDB88320u & (0u - (c & 1u)));
    t.entry[b] = c;
  }
  return t;
}
inline constexpr Table kTable = make_table();

/// CRC-32 of a double's eight bytes, little-endian (the host that generated the header, and
/// every target here, are little-endian).
constexpr std::uint32_t add(std::uint32_t crc, double v) {
  const std::uint64_t bits = double_bits(v);
  for (int byte = 0; byte < 8; ++byte)
    crc = (crc >> 8) ^ kTable.entry[(crc ^ static_cast<std::uint32_t>(bits >> (8 * byte))) & 0xFFu];
  return crc;
}

constexpr std::uint32_t add(std::uint32_t crc, const paper::Electrode& e) {
  for (double v : {e.thickness_m, e.particle_radius_m, e.solid_fraction, e.porosity, e.solid_diffusivity_m2_s,
                   e.max_concentration_mol_m3, e.conductivity_eff_s_m, e.i0_coefficient, e.stoich_init})
    crc = add(crc, v);
  return crc;
}

template <int N>
constexpr std::uint32_t add(std::uint32_t crc, const HermiteTable<N>& t) {
  crc = add(add(crc, t.x_first), t.x_last);
  for (int i = 0; i < N; ++i) crc = add(add(crc, t.y[i]), t.dydx[i]);
  return crc;
}

}  // namespace cell_crc

/// The CRC-32 of a generated configuration's numbers, in the generator's order
/// (host_sim/src/cell/reduced_cell_record.cpp: record_crc32): the record's, then the design-time
/// bias (the constant, its table's range and knots), which the firmware applies to every tick's
/// voltage as much as the cell's own numbers.
template <class Cell>
constexpr std::uint32_t cell_config_crc32() {
  std::uint32_t crc = 0xFFFFFFFFu;
  for (double v : {Cell::kAreaM2, Cell::kTemperatureK, Cell::kTransference, Cell::kElectrolyteInitMolM3,
                   Cell::kSeparatorThicknessM, Cell::kSeparatorPorosity, Cell::kTransportEfficiencyNeg,
                   Cell::kTransportEfficiencySep, Cell::kTransportEfficiencyPos, Cell::kSideRefPotentialV,
                   Cell::kSideExchangeAM2, Cell::kSideAlpha, Cell::kInitialFilmOhmM2, Cell::kFilmMolarMassKgMol,
                   Cell::kFilmDensityKgM3, Cell::kFilmConductivitySM, Cell::kUpperVoltageV, Cell::kLowerVoltageV,
                   Cell::kNominalCapacityAh})
    crc = cell_crc::add(crc, v);
  crc = cell_crc::add(cell_crc::add(crc, Cell::kNeg), Cell::kPos);
  crc = cell_crc::add(cell_crc::add(crc, Cell::kOcpNeg), Cell::kOcpPos);
  crc = cell_crc::add(cell_crc::add(crc, Cell::kDiffusivity), Cell::kConductivity);
  crc = cell_crc::add(crc, Cell::kModelBiasOhm);
  crc = cell_crc::add(cell_crc::add(crc, Cell::kModelBiasTableFirst), Cell::kModelBiasTableLast);
  for (double v : Cell::kModelBiasTableOhm) crc = cell_crc::add(crc, v);
  crc = cell_crc::add(crc, Cell::kModelBiasTableTrustedLast);
  crc = cell_crc::add(crc, Cell::kModelBiasInventoryStep);
  crc = cell_crc::add(cell_crc::add(crc, Cell::kModelBiasLeanFirst), Cell::kModelBiasLeanLast);
  for (double v : Cell::kModelBiasLeanOhm) crc = cell_crc::add(crc, v);
  crc = cell_crc::add(crc, Cell::kModelBiasLeanTrustedLast);
  crc = cell_crc::add(cell_crc::add(crc, Cell::kModelBiasRichFirst), Cell::kModelBiasRichLast);
  for (double v : Cell::kModelBiasRichOhm) crc = cell_crc::add(crc, v);
  crc = cell_crc::add(crc, Cell::kModelBiasRichTrustedLast);
  crc = cell_crc::add(cell_crc::add(crc, Cell::kModelBiasCoveredChargeA), Cell::kModelBiasConstantAloneCovered);
  return ~crc;
}

/// One level of a header's bias table (its first and last knots' stoichiometry, knots, trusted end; 0: none).
constexpr ModelBiasTable<double> bias_level_of(double first, double last, const double (&ohm)[kModelBiasKnots],
                                               double trusted_last) {
  ModelBiasTable<double> t{};
  t.x_first = first;
  t.x_last = last;
  for (int k = 0; k < kModelBiasKnots; ++k) t.ohm[k] = ohm[k];
  if (trusted_last > 0.0) t.x_trusted_last = trusted_last;
  return t;
}

/// A generated configuration's design-time bias tables: the nominal inventory's (kModelBiasTable*)
/// and the lean and rich levels (kModelBiasLean*, kModelBiasRich*, kModelBiasInventoryStep apart).
template <class Cell>
constexpr ModelBiasTables<double> bias_tables_of() {
  static_assert(sizeof(Cell::kModelBiasTableOhm) / sizeof(double) == kModelBiasKnots &&
                    sizeof(Cell::kModelBiasLeanOhm) / sizeof(double) == kModelBiasKnots &&
                    sizeof(Cell::kModelBiasRichOhm) / sizeof(double) == kModelBiasKnots,
                "cell configuration: a bias table has another number of knots than the firmware's table");
  static_assert(kModelBiasLevels == 3, "the header holds three levels: lean, nominal, rich");
  ModelBiasTables<double> t{};
  t.level[0] = bias_level_of(Cell::kModelBiasLeanFirst, Cell::kModelBiasLeanLast, Cell::kModelBiasLeanOhm,
                             Cell::kModelBiasLeanTrustedLast);
  t.level[1] = bias_level_of(Cell::kModelBiasTableFirst, Cell::kModelBiasTableLast, Cell::kModelBiasTableOhm,
                             Cell::kModelBiasTableTrustedLast);
  t.level[2] = bias_level_of(Cell::kModelBiasRichFirst, Cell::kModelBiasRichLast, Cell::kModelBiasRichOhm,
                             Cell::kModelBiasRichTrustedLast);
  t.nu_step = Cell::kModelBiasInventoryStep;
  t.covered_charge_a_min = Cell::kModelBiasCoveredChargeA;
  t.constant_alone_covered = Cell::kModelBiasConstantAloneCovered != 0.0;
  return t;
}

/// The paper cell: its exact expressions (PaperCellTraits), the paper's mesh, its bias.
struct PaperCell {
  using Traits = PaperCellTraits;
  using Mesh = ReducedMesh<>;
  static constexpr const char* kName = "paper";
  static constexpr double kModelBiasOhm = kPaperReducedModelBiasOhm;
  static constexpr ModelBiasTables<double> kModelBiasTable{};  // the constant alone
};

/// A generated configuration: its tables, the mesh the host runs every other cell on (16
/// positive-particle shells: host_sim's AnyCellMesh), the bias the generator computed. Does not
/// compile when the header's numbers do not give its CRC (checked where a build uses the cell).
template <class Cell, class Name>
struct GeneratedCell {
  static constexpr const char* kName = Name::kValue;
  static_assert(cell_config_crc32<Cell>() == Cell::kRecordCrc32,
                "cell configuration: CRC-32 of the header's numbers differs from kRecordCrc32 (edited or damaged; "
                "regenerate with bmssim cell-config)");
  using Traits = Cell;
  using Mesh = ReducedMesh<3, 1, 3, 16, 16>;
  static constexpr double kModelBiasOhm = Cell::kModelBiasOhm;
  static constexpr ModelBiasTables<double> kModelBiasTable = bias_tables_of<Cell>();
};

struct LcoName {
  static constexpr const char* kValue = "lco";
};
struct NmcName {
  static constexpr const char* kValue = "nmc";
};
struct AboutenergyName {
  static constexpr const char* kValue = "aboutenergy";
};
using LcoCell = GeneratedCell<cells::LcoCellTraits, LcoName>;
using NmcCell = GeneratedCell<cells::NmcCellTraits, NmcName>;
using AboutenergyCell = GeneratedCell<cells::AboutenergyCellTraits, AboutenergyName>;

// BMS_CELL_ID comes from the build (CMake BMS_CELL); the preprocessor must see it to pick a cell.
#ifndef BMS_CELL_ID
#define BMS_CELL_ID 0  // NOLINT(cppcoreguidelines-macro-usage): set by the build system, tested by #if
#endif
#if BMS_CELL_ID == 0
using SelectedCell = PaperCell;
#elif BMS_CELL_ID == 1
using SelectedCell = LcoCell;
#elif BMS_CELL_ID == 2
using SelectedCell = NmcCell;
#elif BMS_CELL_ID == 3
using SelectedCell = AboutenergyCell;
#elif BMS_CELL_ID == 4
using SelectedCell = GeneratedCell<cells::FileCellTraits, FileCellName>;
#else
#error "BMS_CELL_ID: 0 paper, 1 lco, 2 nmc, 3 aboutenergy, 4 a BPX file's (CMake: -DBMS_CELL=paper|lco|nmc|aboutenergy, BMS_CELL_FILE)"
#endif

/// A cell choice as the nominal cell make_config takes: the design state's inventory, the
/// initial film, the nominal growth, the bias and the voltage limits, all from the traits.
template <class Scalar, class Choice>
NominalCell nominal_cell_of() {
  using Model = ReducedCell<Scalar, typename Choice::Traits, typename Choice::Mesh>;
  using Cell = typename Choice::Traits;
  return {static_cast<double>(Model::inventory_of(Scalar(Cell::kNeg.stoich_init), Scalar(Cell::kPos.stoich_init))),
          Cell::kInitialFilmOhmM2,
          static_cast<double>(Model::nominal_film_growth_ohm_m2_per_a_m3_s()),
          Choice::kModelBiasOhm,
          Cell::kLowerVoltageV,
          Cell::kUpperVoltageV,
          Choice::kModelBiasTable,
          Cell::kNominalCapacityAh};
}

}  // namespace bms::fw
