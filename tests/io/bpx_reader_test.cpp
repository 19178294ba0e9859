#include "io/bpx_reader.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <nlohmann/json.hpp>
#include <random>
#include <string>

#include "io/input_error.hpp"
#include "io/text_file.hpp"

namespace bms {
namespace {

using nlohmann::json;

constexpr double kFaradayC_mol = 96485.33212;  // C/mol
const std::string kLfpFile = BMS_SHARED_DIR "/data/aboutenergy-lfp18650/lfp_18650_cell_BPX.json";

json lfp_json() { return json::parse(read_text_file(kLfpFile)); }

// read_bpx_text on the real file after `edit`; returns the error message or "(no error)".
std::string error_after(const std::function<void(json&)>& edit) {
  json j = lfp_json();
  edit(j);
  try {
    read_bpx_text(j.dump(), "lfp.json");
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

json& negative(json& j) { return j["Parameterisation"]["Negative electrode"]; }
json& positive(json& j) { return j["Parameterisation"]["Positive electrode"]; }

// Theoretical capacity of an electrode between its stoichiometry limits, in A h.
double electrode_capacity_ah(const CellParameters& p, const ElectrodeParameters& e) {
  return e.solid_fraction * e.thickness_m * p.electrode_area_m2 * e.max_concentration_mol_m3 *
         (e.stoich_max - e.stoich_min) * kFaradayC_mol / 3600.0;
}

TEST(BpxReader, ReadsTheAboutEnergyLfpCell) {
  const CellParameters p = read_bpx(kLfpFile);
  EXPECT_EQ(p.name, "lfp_18650_cell_BPX");
  EXPECT_EQ(p.source, kLfpFile);
  EXPECT_DOUBLE_EQ(p.electrode_area_m2, 0.08959998);
  EXPECT_DOUBLE_EQ(p.lower_voltage_v, 2.0);
  EXPECT_DOUBLE_EQ(p.upper_voltage_v, 3.65);
  EXPECT_DOUBLE_EQ(p.nominal_capacity_ah, 2.0);
  EXPECT_DOUBLE_EQ(p.initial_electrolyte_mol_m3, 1000.0);
  // No side-reaction keys: the Ramadass reaction with the paper's values.
  EXPECT_TRUE(p.side.enabled);
  EXPECT_EQ(p.side.source, "the paper's values");
  EXPECT_DOUBLE_EQ(p.side.exchange_current_a_m2, 4e-9);
  EXPECT_DOUBLE_EQ(p.side.initial_film_resistance_ohm_m2, 3.391e-3);

  const ElectrodeParameters& n = p.negative;
  EXPECT_DOUBLE_EQ(n.particle_radius_m, 4.8e-6);
  EXPECT_DOUBLE_EQ(n.thickness_m, 4.44e-5);
  EXPECT_DOUBLE_EQ(n.solid_fraction, 473004 * 4.8e-6 / 3);
  EXPECT_DOUBLE_EQ(n.surface_area_per_volume_m(), 473004);
  EXPECT_DOUBLE_EQ(n.porosity, 0.20666);
  EXPECT_DOUBLE_EQ(n.transport_efficiency, 0.09395);
  EXPECT_DOUBLE_EQ(n.solid_diffusivity_m2_s, 9.6e-15);
  EXPECT_DOUBLE_EQ(n.max_concentration_mol_m3, 31400);
  EXPECT_DOUBLE_EQ(n.conductivity_eff_s_m, 7.46);
  EXPECT_DOUBLE_EQ(n.i0_coefficient, kFaradayC_mol * 6.872e-6 / (std::sqrt(1000.0) * 31400));
  EXPECT_DOUBLE_EQ(n.stoich_min, 0.0016261);
  EXPECT_DOUBLE_EQ(n.stoich_max, 0.82258);
  EXPECT_DOUBLE_EQ(n.stoich_init, 0.82258);
  EXPECT_DOUBLE_EQ(n.diffusivity_activation_j_mol, 30000);
  EXPECT_DOUBLE_EQ(n.rate_activation_j_mol, 55000);
  ASSERT_TRUE(n.ocp_v && n.entropic_v_k);
  EXPECT_GT(n.ocp_v->value(0.5), 0.05);
  EXPECT_LT(n.ocp_v->value(0.5), 0.3);
  EXPECT_NEAR(n.entropic_v_k->value(0.5), (-0.1112 * 0.5 + 0.02914) / 1000, 1e-9);

  const ElectrodeParameters& q = p.positive;
  EXPECT_DOUBLE_EQ(q.particle_radius_m, 5e-7);
  EXPECT_DOUBLE_EQ(q.solid_fraction, 4418460 * 5e-7 / 3);
  EXPECT_DOUBLE_EQ(q.stoich_init, 0.0875);
  EXPECT_DOUBLE_EQ(q.conductivity_eff_s_m, 0.8);
  ASSERT_TRUE(q.ocp_v && q.entropic_v_k);
  const double u = q.ocp_v->value(0.5);
  EXPECT_TRUE(std::isfinite(u));
  EXPECT_GT(u, 3.2);
  EXPECT_LT(u, 3.5);
  EXPECT_DOUBLE_EQ(q.entropic_v_k->value(0.5), -5.2311e-05);  // table knot
  EXPECT_NEAR(q.entropic_v_k->derivative(0.52), (-6.0211e-05 + 5.2311e-05) / 0.05, 1e-12);

  EXPECT_DOUBLE_EQ(p.separator.thickness_m, 2e-5);
  EXPECT_DOUBLE_EQ(p.separator.porosity, 0.47);
  EXPECT_DOUBLE_EQ(p.separator.transport_efficiency, 0.3222);

  const ElectrolyteParameters& el = p.electrolyte;
  EXPECT_DOUBLE_EQ(el.initial_concentration_mol_m3, 1000.0);
  EXPECT_DOUBLE_EQ(el.transference_number, 0.259);
  EXPECT_NEAR(el.conductivity_s_m->value(1000.0), 0.1297 - 2.51 + 3.329, 1e-12);
  EXPECT_NEAR(el.diffusivity_m2_s->value(1000.0), 8.794e-11 - 3.972e-10 + 4.862e-10, 1e-22);
  EXPECT_DOUBLE_EQ(el.conductivity_activation_j_mol, 17100);
  EXPECT_DOUBLE_EQ(el.diffusivity_activation_j_mol, 17100);

  EXPECT_DOUBLE_EQ(p.thermal.ambient_temperature_k, 298.15);
  EXPECT_DOUBLE_EQ(p.thermal.initial_temperature_k, 298.15);
  EXPECT_DOUBLE_EQ(p.thermal.reference_temperature_k, 298.15);
  EXPECT_DOUBLE_EQ(p.thermal.specific_heat_j_kg_k, 999);
  EXPECT_DOUBLE_EQ(p.thermal.density_kg_m3, 1940);
  EXPECT_DOUBLE_EQ(p.thermal.volume_m3, 1.7e-5);
  EXPECT_DOUBLE_EQ(p.thermal.external_area_m2, 0.00431);
}

// The interpretation (a R / 3, area x pairs, stoichiometry window) must give back the cell's
// nominal capacity from either electrode.
TEST(BpxReader, ElectrodeCapacitiesMatchTheNominalCapacity) {
  const CellParameters p = read_bpx(kLfpFile);
  const double negative_ah = electrode_capacity_ah(p, p.negative);
  const double positive_ah = electrode_capacity_ah(p, p.positive);
  EXPECT_NEAR(negative_ah, p.nominal_capacity_ah, 0.1 * p.nominal_capacity_ah);
  EXPECT_NEAR(positive_ah, negative_ah, 0.01 * negative_ah);
}

TEST(BpxReader, AlternativeFieldForms) {
  json j = lfp_json();
  negative(j)["Diffusivity [m2.s-1]"] = "1e-14 * (1 + x)";  // evaluated at x = 0.5
  positive(j)["OCP [V]"] = 3.3;
  j["Parameterisation"]["Electrolyte"]["Conductivity [S.m-1]"] =
      json{{"x", {0, 2000}}, {"y", {0.0, 2.0}}};
  j["Parameterisation"]["Cell"]["Number of electrode pairs connected in parallel to make a cell"] =
      2;
  j["Header"]["BPX"] = "0.1.2";
  negative(j).erase("Entropic change coefficient [V.K-1]");
  j["Parameterisation"]["Cell"].erase("Initial temperature [K]");
  j["Parameterisation"]["Cell"]["Ambient temperature [K]"] = 288.15;
  const CellParameters p = read_bpx_text(j.dump(), "variant.json");
  EXPECT_DOUBLE_EQ(p.negative.solid_diffusivity_m2_s, 1.5e-14);
  EXPECT_DOUBLE_EQ(p.positive.ocp_v->value(0.3), 3.3);
  EXPECT_DOUBLE_EQ(p.positive.ocp_v->derivative(0.3), 0.0);
  EXPECT_DOUBLE_EQ(p.electrolyte.conductivity_s_m->value(1000.0), 1.0);
  EXPECT_DOUBLE_EQ(p.electrolyte.conductivity_s_m->derivative(1000.0), 1e-3);
  EXPECT_DOUBLE_EQ(p.electrode_area_m2, 2 * 0.08959998);
  EXPECT_FALSE(p.negative.entropic_v_k);
  EXPECT_DOUBLE_EQ(p.thermal.initial_temperature_k, 288.15);
  EXPECT_EQ(p.name, "variant");
}

TEST(BpxReader, MissingFieldNamesTheFullPath) {
  EXPECT_EQ(error_after([](json& j) { negative(j).erase("Particle radius [m]"); }),
            "lfp.json: missing field 'Parameterisation.Negative electrode.Particle radius [m]'");
  EXPECT_EQ(error_after([](json& j) { j["Parameterisation"].erase("Separator"); }),
            "lfp.json: missing field 'Parameterisation.Separator'");
  EXPECT_EQ(error_after([](json& j) { j.erase("Header"); }), "lfp.json: missing field 'Header'");
  EXPECT_EQ(error_after([](json& j) {
              j["Parameterisation"]["Electrolyte"].erase("Diffusivity [m2.s-1]");
            }),
            "lfp.json: missing field 'Parameterisation.Electrolyte.Diffusivity [m2.s-1]'");
}

TEST(BpxReader, BadExpressionNamesTheFieldAndColumn) {
  const std::string broken = error_after(
      [](json& j) { positive(j)["OCP [V]"] = positive(j)["OCP [V]"].get<std::string>() + " + )"; });
  EXPECT_NE(broken.find("lfp.json: field 'Parameterisation.Positive electrode.OCP [V]': "
                        "unexpected ')' at column"),
            std::string::npos)
      << broken;
  const std::string unknown = error_after([](json& j) { negative(j)["OCP [V]"] = "tanx(x)"; });
  EXPECT_EQ(unknown.rfind("lfp.json: field 'Parameterisation.Negative electrode.OCP [V]': "
                          "unknown function 'tanx'",
                          0),
            0u)
      << unknown;
  EXPECT_NE(error_after([](json& j) {
              negative(j)["OCP [V]"] = "1 / (x - x)";
            }).find("'Parameterisation.Negative electrode.OCP [V]' evaluates to"),
            std::string::npos);
}

TEST(BpxReader, OutOfRangeValuesNameFieldValueAndRange) {
  EXPECT_EQ(error_after([](json& j) { negative(j)["Thickness [m]"] = -4.44e-5; }),
            "lfp.json: field 'Parameterisation.Negative electrode.Thickness [m]' = -4.44e-05 is "
            "out of range (allowed: [1e-07, 0.005])");
  EXPECT_EQ(error_after([](json& j) { j["Parameterisation"]["Separator"]["Porosity"] = 1.2; }),
            "lfp.json: field 'Parameterisation.Separator.Porosity' = 1.2 is out of range "
            "(allowed: (0, 1])");
  EXPECT_EQ(error_after([](json& j) { positive(j)["Maximum stoichiometry"] = 1.5; }),
            "lfp.json: field 'Parameterisation.Positive electrode.Maximum stoichiometry' = 1.5 "
            "is out of range (allowed: [0, 1])");
  EXPECT_EQ(error_after([](json& j) { positive(j)["Minimum stoichiometry"] = 0.96; }),
            "lfp.json: field 'Parameterisation.Positive electrode.Minimum stoichiometry' = 0.96 "
            "must be less than 'Maximum stoichiometry' = 0.95038");
  EXPECT_NE(error_after([](json& j) { negative(j)["Maximum concentration [mol.m-3]"] = 0; })
                .find("'Parameterisation.Negative electrode.Maximum concentration [mol.m-3]' = 0 "
                      "is out of range"),
            std::string::npos);
  EXPECT_NE(error_after([](json& j) {
              j["Parameterisation"]["Cell"]["Ambient temperature [K]"] = 25;
            }).find("Ambient temperature [K]' = 25 is out of range (allowed: [173.15, 473.15])"),
            std::string::npos);
  EXPECT_NE(error_after([](json& j) {
              negative(j)["Surface area per unit volume [m-1]"] = 600000;
            }).find("exceeds the whole volume"),
            std::string::npos);
  EXPECT_NE(error_after([](json& j) {
              j["Parameterisation"]["Cell"]
               ["Number of electrode pairs connected in parallel to make a cell"] = 1.5;
            }).find("= 1.5 must be a whole number"),
            std::string::npos);
  EXPECT_NE(error_after([](json& j) {
              j["Parameterisation"]["Cell"]["Upper voltage cut-off [V]"] = 1.5;
            }).find("must be below 'Upper voltage cut-off [V]' = 1.5"),
            std::string::npos);
}

// Physically absurd values (a solid diffusivity of 1e10 m2/s hung the solver, a
// thickness of 1e10 m failed deep in it) are input errors naming the field and the range.
TEST(BpxReader, PhysicallyAbsurdValuesAreInputErrors) {
  EXPECT_EQ(error_after([](json& j) { negative(j)["Diffusivity [m2.s-1]"] = 1e10; }),
            "lfp.json: field 'Parameterisation.Negative electrode.Diffusivity [m2.s-1]' evaluates to "
            "10000000000 (derivative 0) at x = 0.5; allowed values: [1e-25, 1e-08]");
  EXPECT_EQ(error_after([](json& j) { j["Parameterisation"]["Separator"]["Thickness [m]"] = 1e10; }),
            "lfp.json: field 'Parameterisation.Separator.Thickness [m]' = 10000000000 is out of range "
            "(allowed: [1e-07, 0.005])");
  const auto names = [](const std::string& msg, const std::string& field) {
    return msg.find("'" + field + "'") != std::string::npos && msg.find("out of range") != std::string::npos;
  };
  EXPECT_TRUE(names(error_after([](json& j) { positive(j)["Particle radius [m]"] = 5.0; }),
                    "Parameterisation.Positive electrode.Particle radius [m]"));
  EXPECT_TRUE(names(error_after([](json& j) { positive(j)["Conductivity [S.m-1]"] = 1e12; }),
                    "Parameterisation.Positive electrode.Conductivity [S.m-1]"));
  EXPECT_TRUE(names(error_after([](json& j) { negative(j)["Reaction rate constant [mol.m-2.s-1]"] = 1e3; }),
                    "Parameterisation.Negative electrode.Reaction rate constant [mol.m-2.s-1]"));
  EXPECT_TRUE(names(error_after([](json& j) { j["Parameterisation"]["Cell"]["Electrode area [m2]"] = 1e9; }),
                    "Parameterisation.Cell.Electrode area [m2]"));
  EXPECT_TRUE(names(error_after([](json& j) {
                      j["Parameterisation"]["Electrolyte"]["Initial concentration [mol.m-3]"] = 1e7;
                    }),
                    "Parameterisation.Electrolyte.Initial concentration [mol.m-3]"));
  EXPECT_NE(error_after([](json& j) { j["Parameterisation"]["Electrolyte"]["Diffusivity [m2.s-1]"] = 1.0; })
                .find("'Parameterisation.Electrolyte.Diffusivity [m2.s-1]' evaluates to 1"),
            std::string::npos);
  EXPECT_NE(error_after([](json& j) { j["Parameterisation"]["Electrolyte"]["Conductivity [S.m-1]"] = 1e5; })
                .find("'Parameterisation.Electrolyte.Conductivity [S.m-1]' evaluates to 100000"),
            std::string::npos);
}

// A free electrolyte gap (PyBaMM sets allow separator porosity 1) and PyBaMM's thermodynamic
// factor, a number or an expression of the concentration x.
TEST(BpxReader, SeparatorPorosityOneAndThermodynamicFactor) {
  json j = lfp_json();
  j["Parameterisation"]["Separator"]["Porosity"] = 1.0;
  const CellParameters plain = read_bpx_text(j.dump(), "lfp.json");
  EXPECT_EQ(plain.separator.porosity, 1.0);
  EXPECT_EQ(plain.electrolyte.thermodynamic_factor, nullptr);
  j["Parameterisation"]["Electrolyte"]["Thermodynamic factor"] = "1 + 0.5 * x / 1000";
  const CellParameters with = read_bpx_text(j.dump(), "lfp.json");
  ASSERT_NE(with.electrolyte.thermodynamic_factor, nullptr);
  EXPECT_DOUBLE_EQ(with.electrolyte.thermodynamic_factor->value(2000.0), 2.0);
  EXPECT_NE(error_after([](json& k) { k["Parameterisation"]["Electrolyte"]["Thermodynamic factor"] = -1.0; })
                .find("'Parameterisation.Electrolyte.Thermodynamic factor' evaluates to -1"),
            std::string::npos);
}

TEST(BpxReader, WrongTypesAndTables) {
  EXPECT_EQ(error_after([](json& j) { negative(j)["Thickness [m]"] = "4.44e-5"; }),
            "lfp.json: field 'Parameterisation.Negative electrode.Thickness [m]' must be a "
            "number, not string");
  EXPECT_EQ(error_after([](json& j) { j["Parameterisation"]["Cell"] = json::array(); }),
            "lfp.json: field 'Parameterisation.Cell' must be an object, not array");
  EXPECT_NE(error_after([](json& j) { negative(j)["OCP [V]"] = true; })
                .find("must be a number, an expression string or an {\"x\": [...], \"y\": [...]} "
                      "table, not boolean"),
            std::string::npos);
  EXPECT_EQ(error_after(
                [](json& j) { positive(j)["Entropic change coefficient [V.K-1]"]["x"][3] = 0.01; }),
            "lfp.json: field 'Parameterisation.Positive electrode.Entropic change coefficient "
            "[V.K-1]': table x must strictly increase, but x[3] = 0.01 follows x[2] = 0.1");
  EXPECT_EQ(error_after([](json& j) {
              positive(j)["Entropic change coefficient [V.K-1]"]["y"][2] = "oops";
            }),
            "lfp.json: field 'Parameterisation.Positive electrode.Entropic change coefficient "
            "[V.K-1].y[2]' must be a number, not string");
  EXPECT_NE(error_after([](json& j) {
              negative(j)["Particle"] = json::object();
            }).find("blended electrode"),
            std::string::npos);
}

TEST(BpxReader, VersionAndSyntax) {
  EXPECT_EQ(error_after([](json& j) { j["Header"]["BPX"] = 1.0; }),
            "lfp.json: field 'Header.BPX' = 1.0: unsupported BPX version (this reader supports "
            "0.1.x)");
  EXPECT_NE(
      error_after([](json& j) { j["Header"]["BPX"] = "0.10.0"; }).find("unsupported BPX version"),
      std::string::npos);
  try {
    read_bpx_text("{\"Header\": {\"BPX\": 0.1,}", "bad.json");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_EQ(std::string(e.what()).rfind(
                  "bad.json: not valid JSON (byte 24): parse error at line 1, column 24: syntax "
                  "error while parsing object key - unexpected '}'",
                  0),
              0u)
        << e.what();
  }
  EXPECT_THROW(read_bpx_text("", "empty.json"), InputError);
  EXPECT_THROW(read_bpx_text("[1, 2]", "array.json"), InputError);
  try {
    read_bpx(BMS_SOURCE_DIR "/no/such/file.json");
    FAIL() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("no/such/file.json: cannot read"), std::string::npos);
  }
}

// The side reaction's constants under PyBaMM's SEI names in "User-defined"; each missing one
// keeps the paper's value; a bad one is refused with its full path.
TEST(BpxReader, SideReactionFromUserDefinedKeys) {
  json j = lfp_json();
  json& u = j["Parameterisation"]["User-defined"];
  u["SEI reaction exchange current density [A.m-2]"] = 2e-9;
  u["SEI open-circuit potential [V]"] = 0.38;
  u["SEI partial molar volume [m3.mol-1]"] = 20.0;
  u["SEI resistivity [Ohm.m]"] = 2e5;        // PyBaMM's example value
  u["Initial SEI thickness [m]"] = 1e-8;      // -> 2e-3 ohm m2
  const CellParameters p = read_bpx_text(j.dump(), "lfp.json");
  EXPECT_TRUE(p.side.enabled);
  EXPECT_NE(p.side.source.find("User-defined"), std::string::npos);
  EXPECT_DOUBLE_EQ(p.side.exchange_current_a_m2, 2e-9);
  EXPECT_DOUBLE_EQ(p.side.reference_potential_v, 0.38);
  EXPECT_DOUBLE_EQ(p.side.transfer_coefficient, 0.5);  // the paper's
  EXPECT_DOUBLE_EQ(p.side.molar_mass_kg_mol / p.side.density_kg_m3, 20.0);
  EXPECT_DOUBLE_EQ(p.side.film_conductivity_s_m, 1.0 / 2e5);
  EXPECT_DOUBLE_EQ(p.side.initial_film_resistance_ohm_m2, 2e-3);

  EXPECT_NE(error_after([](json& k) {
              k["Parameterisation"]["User-defined"]["SEI reaction exchange current density [A.m-2]"] = -1.0;
            }).find("Parameterisation.User-defined.SEI reaction exchange current density [A.m-2]"),
            std::string::npos);
  EXPECT_NE(error_after([](json& k) {
              k["Parameterisation"]["User-defined"]["Initial SEI thickness [m]"] = 1e-9;
              k["Parameterisation"]["User-defined"]["Initial SEI resistance [Ohm.m2]"] = 1e-3;
            }).find("give one"),
            std::string::npos);
  EXPECT_NE(error_after([](json& k) { k["Parameterisation"]["User-defined"] = 3; }).find("User-defined"),
            std::string::npos);
}

// The cell's own effects (diagnose --write-cell) under "User-defined": absent = off; a value out
// of the truth model's range is refused with its full path.
TEST(BpxReader, CellEffectsFromUserDefinedKeys) {
  EXPECT_FALSE(read_bpx_text(lfp_json().dump(), "lfp.json").effects.any());
  json j = lfp_json();
  json& u = j["Parameterisation"]["User-defined"];
  u["Contact resistance [Ohm]"] = 0.003;
  u["OCP hysteresis half-gap [V]"] = 0.012;
  u["OCP hysteresis rate per state of charge [-]"] = 30.0;
  u["Lumped heat transfer coefficient [W.K-1]"] = 0.05;
  u["Positive particle-size log-normal standard deviation [-]"] = 0.4;
  const CellParameters p = read_bpx_text(j.dump(), "lfp.json");
  EXPECT_DOUBLE_EQ(p.effects.contact_resistance_ohm, 0.003);
  EXPECT_DOUBLE_EQ(p.effects.hysteresis_v, 0.012);
  EXPECT_DOUBLE_EQ(p.effects.hysteresis_rate_per_soc, 30.0);
  EXPECT_DOUBLE_EQ(p.effects.thermal_h_w_per_k, 0.05);
  EXPECT_DOUBLE_EQ(p.effects.particle_size_sigma, 0.4);
  EXPECT_EQ(p.side.source, SideReactionParameters{}.source);  // no SEI key: the paper's reaction
  EXPECT_NE(error_after([](json& k) { k["Parameterisation"]["User-defined"]["Contact resistance [Ohm]"] = 2.0; })
                .find("Parameterisation.User-defined.Contact resistance [Ohm]"),
            std::string::npos);
  EXPECT_NE(error_after([](json& k) { k["Parameterisation"]["User-defined"]["OCP hysteresis half-gap [V]"] = -0.01; })
                .find("OCP hysteresis half-gap"),
            std::string::npos);
}

// Byte-level mutations of the real file: every outcome is a CellParameters or an InputError.
TEST(BpxReader, MutatedFilesFailCleanly) {
  const std::string original = read_text_file(kLfpFile);
  std::mt19937 rng(2024);
  std::uniform_int_distribution<std::size_t> where(0, original.size() - 1);
  std::uniform_int_distribution<int> byte(0, 255);
  const std::string interesting = "{}[]\",:-.0e9xX)( ";
  std::uniform_int_distribution<std::size_t> pick(0, interesting.size() - 1);
  int accepted = 0;
  for (int i = 0; i < 400; ++i) {
    std::string text = original;
    for (int k = 0; k < 1 + i % 3; ++k) {
      const std::size_t at = where(rng);
      text[at] = (i % 2 == 0) ? interesting[pick(rng)] : static_cast<char>(byte(rng));
    }
    try {
      read_bpx_text(text, "fuzz.json");
      ++accepted;
    } catch (const InputError&) {
    }
  }
  EXPECT_GT(accepted, 0);  // some mutations only touch descriptions
}

}  // namespace
}  // namespace bms

namespace bms {
namespace {

// A key of the schema with its unit written another way is converted; a unit it does not know,
// or a key the section does not have, is an input error naming the key (never dropped: an
// activation energy in kJ/mol read as absent made a -5 C discharge last 5x too long).
TEST(BpxReader, UnitSpellingsConvertedUnknownKeysRefused) {
  const CellParameters ref = read_bpx(kLfpFile);
  json j = lfp_json();
  const double ea = negative(j)["Diffusivity activation energy [J.mol-1]"].get<double>();
  ASSERT_GT(ea, 0.0);
  negative(j).erase("Diffusivity activation energy [J.mol-1]");
  negative(j)["Diffusivity activation energy [kJ.mol-1]"] = ea / 1000.0;
  const double ea_rate = positive(j)["Reaction rate constant activation energy [J.mol-1]"].get<double>();
  positive(j).erase("Reaction rate constant activation energy [J.mol-1]");
  positive(j)["Reaction rate constant activation energy [J/mol]"] = ea_rate;
  const double t_m = negative(j)["Thickness [m]"].get<double>();
  negative(j).erase("Thickness [m]");
  negative(j)["Thickness [um]"] = t_m * 1e6;
  const CellParameters p = read_bpx_text(j.dump(), "units.json");
  EXPECT_NEAR(p.negative.diffusivity_activation_j_mol, ref.negative.diffusivity_activation_j_mol, 1e-9 * ea);
  EXPECT_DOUBLE_EQ(p.positive.rate_activation_j_mol, ref.positive.rate_activation_j_mol);
  EXPECT_NEAR(p.negative.thickness_m, ref.negative.thickness_m, 1e-12);

  EXPECT_EQ(error_after([](json& j2) {
              negative(j2).erase("Diffusivity activation energy [J.mol-1]");
              negative(j2)["Diffusivity activation energy [kcal/mol]"] = 8.0;
            }),
            "lfp.json: field 'Parameterisation.Negative electrode.Diffusivity activation energy [kcal/mol]' has a unit "
            "this reader cannot convert to the schema's [J.mol-1]; write it in [J.mol-1]");
  EXPECT_NE(error_after([](json& j2) { positive(j2)["Activation energy [J.mol-1]"] = 3e4; })
                .find("field 'Parameterisation.Positive electrode.Activation energy [J.mol-1]' is not a key of the BPX "
                      "schema's section"),
            std::string::npos);
  EXPECT_NE(error_after([](json& j2) { j2["Parameterisation"]["Cell"]["Nominal capacity [A.h]"] = 2.0; })
                .find("'Parameterisation.Cell.Nominal capacity [A.h]' is not a key"),
            std::string::npos);
}

}  // namespace
}  // namespace bms

namespace bms {
namespace {

// An electrode's diffusivity as an expression in the stoichiometry x: its value at x = 0.5 is
// the constant, the truth takes D(x) / D(0.5) as a factor; a number leaves no factor (the plain
// model bit for bit); the knee profile's User-defined keys are read with their ranges.
TEST(BpxReader, StoichiometryDependentDiffusivityAndItsProfileKeys) {
  json j = lfp_json();
  EXPECT_EQ(read_bpx_text(j.dump(), "lfp.json").positive.solid_diffusivity_factor, nullptr);
  positive(j)["Diffusivity [m2.s-1]"] = "6.873e-17 * 10 ** (-2 * (x - 0.5))";
  j["Parameterisation"]["User-defined"]["Positive diffusivity profile log10 factor at full lithiation [-]"] = -1.0;
  j["Parameterisation"]["User-defined"]["Positive diffusivity profile knee stoichiometry [-]"] = 0.7;
  const CellParameters p = read_bpx_text(j.dump(), "lfp.json");
  EXPECT_DOUBLE_EQ(p.positive.solid_diffusivity_m2_s, 6.873e-17);
  ASSERT_NE(p.positive.solid_diffusivity_factor, nullptr);
  EXPECT_NEAR(p.positive.solid_diffusivity_factor->value(0.5), 1.0, 1e-12);
  EXPECT_NEAR(p.positive.solid_diffusivity_factor->value(1.0), 0.1, 1e-12);
  EXPECT_EQ(p.effects.diffusivity_profile_positive, -1.0);
  EXPECT_EQ(p.effects.diffusivity_profile_positive_knee, 0.7);
  j["Parameterisation"]["User-defined"]["Positive diffusivity profile knee stoichiometry [-]"] = 1.5;
  EXPECT_THROW(read_bpx_text(j.dump(), "lfp.json"), InputError);
}

// The cathode's resistive reactant: three User-defined keys, read with their ranges; absent is off.
TEST(BpxReader, ResistiveReactantKeys) {
  json j = lfp_json();
  EXPECT_EQ(read_bpx_text(j.dump(), "lfp.json").effects.resistive_reactant_positive_ohm_m2, 0.0);
  auto& u = j["Parameterisation"]["User-defined"];
  u["Positive resistive reactant resistance [Ohm.m2]"] = 0.02;
  u["Positive resistive reactant log10 rise at full lithiation [-]"] = 2.5;
  u["Positive resistive reactant knee stoichiometry [-]"] = 0.65;
  const CellParameters p = read_bpx_text(j.dump(), "lfp.json");
  EXPECT_EQ(p.effects.resistive_reactant_positive_ohm_m2, 0.02);
  EXPECT_EQ(p.effects.resistive_reactant_positive_log10, 2.5);
  EXPECT_EQ(p.effects.resistive_reactant_positive_knee, 0.65);
  EXPECT_TRUE(p.effects.any());
  u["Positive resistive reactant log10 rise at full lithiation [-]"] = 9.0;
  try {
    read_bpx_text(j.dump(), "lfp.json");
    FAIL() << "a rise of 9 decades was accepted";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find("Positive resistive reactant log10 rise"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace bms
