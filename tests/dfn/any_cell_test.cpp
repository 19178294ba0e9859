// Any cell: the LCO and NMC templates (loaded, capacity as stated, a 1C discharge within the
// window), the firmware's cell as data (tables within their stated error; the generated header
// and the host's runtime traits the same model), and bad cell files refused with the field named.
#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <sstream>
#include <string>

#include <nlohmann/json.hpp>

#include "bms/fw/cells/lco_cell.hpp"
#include "bms/fw/config/cell_choice.hpp"
#include "bms/fw/model/reduced_cell.hpp"
#include "cell/reduced_cell_record.hpp"
#include "io/bpx_reader.hpp"
#include "io/input_error.hpp"
#include "io/text_file.hpp"
#include "sim/cell_catalog.hpp"
#include "sim/cycler.hpp"

namespace bms {
namespace {

constexpr double kFaradayC_mol = 96485.33212;

// Charge between the voltage limits at equilibrium (A h): the electrodes' stoichiometry windows.
double window_capacity_ah(const CellParameters& c) {
  const auto q = [&](const ElectrodeParameters& e) {
    return e.max_concentration_mol_m3 * e.solid_fraction * e.thickness_m * c.electrode_area_m2 *
           (e.stoich_max - e.stoich_min) * kFaradayC_mol / 3600.0;
  };
  return std::min(q(c.negative), q(c.positive));
}

class Template : public ::testing::TestWithParam<const char*> {};

// Validate-style check of a template: it loads, its windows hold the stated capacity, the
// equilibrium voltages at the window ends are the voltage limits, and a 1C CC discharge from
// 100 % state of charge reaches the lower limit within the window delivering most of it.
TEST_P(Template, LoadsHoldsItsCapacityAndDischargesAt1C) {
  const CellParameters c = load_cell(GetParam());
  EXPECT_EQ(c.name, GetParam());
  EXPECT_TRUE(c.side.enabled);
  EXPECT_NEAR(window_capacity_ah(c) / c.nominal_capacity_ah, 1.0, 0.025);
  const double v_full = c.positive.ocp_v->value(c.positive.stoich_min) - c.negative.ocp_v->value(c.negative.stoich_max);
  const double v_empty = c.positive.ocp_v->value(c.positive.stoich_max) - c.negative.ocp_v->value(c.negative.stoich_min);
  EXPECT_NEAR(v_full, c.upper_voltage_v, 0.01);
  EXPECT_NEAR(v_empty, c.lower_voltage_v, 0.01);

  SimulationConfig cfg;
  cfg.cell = c;
  cfg.mesh = {10, 5, 10, 10};
  cfg.dt_s = 10.0;
  cfg.temperature_k = c.thermal.ambient_temperature_k;
  cfg.ic = default_initial_conditions(c);
  CccvProtocol p;
  p.cycles = 1;
  p.current_a = c.nominal_capacity_ah;
  p.cv_end_current_a = 0.1 * c.nominal_capacity_ah;
  p.v_min = c.lower_voltage_v;
  p.v_max = c.upper_voltage_v;
  const SimulationResult r = run_cccv(cfg, p);
  double cc_ah = 0.0, v_min_seen = 1e9, v_max_seen = 0.0;
  for (const SampleRecord& s : r.samples) {
    if (s.mode == Mode::cc_discharge) cc_ah = s.charge_ah;
    v_min_seen = std::min(v_min_seen, s.voltage_v);
    v_max_seen = std::max(v_max_seen, s.voltage_v);
  }
  RecordProperty("cc_discharge_1c_ah", std::to_string(cc_ah));
  EXPECT_GT(cc_ah, 0.85 * c.nominal_capacity_ah);
  EXPECT_LT(cc_ah, 1.02 * c.nominal_capacity_ah);
  EXPECT_GT(v_min_seen, c.lower_voltage_v - 0.01);
  EXPECT_LT(v_max_seen, c.upper_voltage_v + 0.01);
}

INSTANTIATE_TEST_SUITE_P(AnyCell, Template, ::testing::Values("lco", "nmc"));

// The firmware's tables stay within the error the generator states, which is small against the
// film's signal (about 3 mV drop): OCP within 30 uV, transport within 0.1 %.
TEST(CellRecord, TablesWithinTheirStatedError) {
  // (Not the paper cell: its firmware keeps the exact expressions of PaperCellTraits.)
  for (const char* name : {"aboutenergy", "lco", "nmc"}) {
    const ReducedCellRecord r = make_reduced_cell_record(load_cell(name));
    EXPECT_LT(r.ocp_neg_max_err_v, 3e-5) << name;
    EXPECT_LT(r.ocp_pos_max_err_v, 3e-5) << name;
    EXPECT_LT(r.diffusivity_max_rel_err, 1e-3) << name;
    EXPECT_LT(r.conductivity_max_rel_err, 1e-3) << name;
  }
}

// The committed generated header is what the generator writes today (regenerated with the same
// bias), and the model over it is the model over the host's runtime traits, tick for tick.
TEST(CellRecord, GeneratedHeaderIsTheRuntimeModel) {
  using Generated = fw::cells::LcoCellTraits;
  const ReducedCellRecord r = make_reduced_cell_record(load_cell("lco"));
  EXPECT_EQ(record_crc32(r, Generated::kModelBiasOhm, fw::LcoCell::kModelBiasTable), Generated::kRecordCrc32);
  const std::string committed = read_text_file(BMS_SOURCE_DIR "/firmware/include/bms/fw/cells/lco_cell.hpp");
  EXPECT_EQ(cell_header_text(r, "LcoCellTraits", Generated::kModelBiasOhm, fw::LcoCell::kModelBiasTable), committed)
      << "regenerate: bmssim cell-config --cell lco --out DIR (scripts/generate-cells.sh)";

  const RuntimeCellScope scope(r);
  fw::ReducedCell<double, Generated, AnyCellMesh> a;
  fw::ReducedCell<double, RuntimeCellTraits, AnyCellMesh> b;
  a.init_default();
  b.init_default();
  for (int k = 0; k < 600; ++k) {
    const double i_a = k < 300 ? 0.8 : -0.8;
    const auto ra = a.step_current(i_a, Generated::kInitialFilmOhmM2, 1.0);
    const auto rb = b.step_current(i_a, Generated::kInitialFilmOhmM2, 1.0);
    ASSERT_EQ(ra.voltage_v, rb.voltage_v) << "tick " << k;
    ASSERT_EQ(ra.j_side_a_m3, rb.j_side_a_m3) << "tick " << k;
  }
  const auto va = a.step_voltage(4.0, Generated::kInitialFilmOhmM2, 1.0);
  const auto vb = b.step_voltage(4.0, Generated::kInitialFilmOhmM2, 1.0);
  EXPECT_EQ(va.current_a, vb.current_a);
  EXPECT_TRUE(va.converged);
}

// The reduced model of a generated cell follows the truth DFN at rest and under 1C within what
// its reductions allow (the design-time bias removes the constant part).
TEST(CellRecord, ReducedModelTracksTheTruthOpenCircuit) {
  for (const char* name : {"aboutenergy", "lco", "nmc"}) {
    const CellParameters c = load_cell(name);
    const ReducedCellRecord r = make_reduced_cell_record(c);
    const RuntimeCellScope scope(r);
    fw::ReducedCell<double, RuntimeCellTraits, AnyCellMesh> m;
    m.init_default();
    const double ocv = c.positive.ocp_v->value(c.positive.stoich_init) - c.negative.ocp_v->value(c.negative.stoich_init);
    // At rest the model's voltage is the open-circuit voltage less the side current's tiny drop.
    EXPECT_NEAR(m.peek_voltage(0.0, c.side.initial_film_resistance_ohm_m2, 1.0), ocv, 1e-4) << name;
  }
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

// A wrong or incomplete cell file is refused before any model is built, naming the field.
TEST(CellRecord, BadCellFilesAreRefusedWithTheField) {
  const nlohmann::json good = nlohmann::json::parse(read_text_file(cell_template_file("lco")));
  nlohmann::json missing = good;
  missing["Parameterisation"]["Positive electrode"].erase("Maximum concentration [mol.m-3]");
  EXPECT_NE(error_of([&] { read_bpx_text(missing.dump(), "lco-broken.json"); })
                .find("Parameterisation.Positive electrode.Maximum concentration [mol.m-3]"),
            std::string::npos);
  // An OCP that is finite at the window's three check points but not over the firmware's table.
  nlohmann::json bad_ocp = good;
  bad_ocp["Parameterisation"]["Negative electrode"]["OCP [V]"] = "0.1 + 0.01 * log(x - 0.1832)";
  bad_ocp["Parameterisation"]["Negative electrode"]["Minimum stoichiometry"] = 0.2;
  std::string msg;
  try {
    const CellParameters c = read_bpx_text(bad_ocp.dump(), "lco-bad-ocp.json");
    msg = error_of([&] { make_reduced_cell_record(c); });
  } catch (const InputError& e) {
    msg = e.what();
  }
  EXPECT_NE(msg.find("Negative electrode.OCP [V]"), std::string::npos) << msg;
  nlohmann::json bad_sei = good;
  bad_sei["Parameterisation"]["User-defined"]["SEI resistivity [Ohm.m]"] = "high";
  EXPECT_NE(error_of([&] { read_bpx_text(bad_sei.dump(), "lco-bad-sei.json"); })
                .find("Parameterisation.User-defined.SEI resistivity [Ohm.m]"),
            std::string::npos);
}

}  // namespace
}  // namespace bms
