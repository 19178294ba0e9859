// Effects outside physical ranges are input errors naming the effect (a contact
// resistance of 1e6 ohm failed deep in the solver with exit 1).
#include <gtest/gtest.h>

#include <cmath>
#include <string>

#include "cell/paper_cell.hpp"
#include "dfn/dfn_model.hpp"
#include "io/input_error.hpp"

namespace bms {
namespace {

std::string error_of(const ModelEffects& e) {
  const CellParameters cell = make_paper_cell();
  try {
    DfnModel m(cell, DfnMesh{}, cell.thermal.ambient_temperature_k, e);
  } catch (const InputError& x) {
    return x.what();
  }
  return "(no error)";
}

TEST(DfnModelRanges, EffectsOutsidePhysicalRanges) {
  ModelEffects e;
  e.contact_resistance_ohm = 1e6;
  EXPECT_NE(error_of(e).find("contact_resistance: must be in [0, 1] ohm"), std::string::npos) << error_of(e);
  e.contact_resistance_ohm = std::nan("");
  EXPECT_NE(error_of(e).find("contact_resistance"), std::string::npos);
  e.contact_resistance_ohm = 0.5;
  EXPECT_EQ(error_of(e), "(no error)");
  ModelEffects t;
  t.thermal_h_w_per_k = 1e9;
  EXPECT_NE(error_of(t).find("thermal: heat-transfer coefficient must be in [0, 1e6] W/K"), std::string::npos);
}

}  // namespace
}  // namespace bms
