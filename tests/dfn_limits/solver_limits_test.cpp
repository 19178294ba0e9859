// The truth's solver cannot hang: a model it cannot integrate ends in a
// RuntimeFailure that names the limit, the time reached and what to try. Run by ctest with a
// time limit (tests/CMakeLists.txt), so a regression to a hang fails instead of blocking.
#include <gtest/gtest.h>

#include <string>

#include "cell/paper_cell.hpp"
#include "io/bpx_reader.hpp"
#include "io/input_error.hpp"
#include "io/text_file.hpp"
#include "sim/cycler.hpp"

namespace bms {
namespace {

const std::string kMinimalBpx = BMS_SOURCE_DIR "/tests/fuzz/corpus/bpx/minimal_valid.json";

SimulationConfig config_of(const CellParameters& cell) {
  SimulationConfig cfg;
  cfg.cell = cell;
  cfg.temperature_k = cell.thermal.ambient_temperature_k;
  cfg.ic = default_initial_conditions(cell);
  return cfg;
}

CccvProtocol one_cycle(const CellParameters& cell) {
  CccvProtocol p;
  p.cycles = 1;
  p.current_a = 2.5;  // `simulate`'s default current
  p.v_min = cell.lower_voltage_v;
  p.v_max = cell.upper_voltage_v;
  return p;
}

std::string failure_of(const SimulationConfig& cfg, const CccvProtocol& p) {
  try {
    run_cccv(cfg, p);
  } catch (const RuntimeFailure& e) {
    return e.what();
  }
  return "(no failure)";
}

TEST(SolverLimits, AbsurdSolidDiffusivityEndsInACrawlFailure) {
  // Past the reader (which now refuses it as an input error): a solid diffusivity of 1e10
  // m2/s. IDA then takes 1e-8 s steps with a Newton failure every other step, and the run
  // used never to return.
  CellParameters cell = read_bpx_text(read_text_file(kMinimalBpx), "minimal.json");
  cell.negative.solid_diffusivity_m2_s = 1e10;
  auto cfg = config_of(cell);
  cfg.mesh = DfnMesh{20, 20, 20, 10};  // crawls as the default mesh does, at half the cost (ASan builds)
  const std::string msg = failure_of(cfg, one_cycle(cell));
  EXPECT_NE(msg.find("solver is crawling"), std::string::npos) << msg;
  EXPECT_NE(msg.find("cycle 1, cc_discharge"), std::string::npos) << msg;
  EXPECT_NE(msg.find("check diffusivities"), std::string::npos) << msg;
}

TEST(SolverLimits, StepLimitCountsAcrossTheOneStepLoop) {
  // One advance over a whole 1C discharge takes a few hundred internal steps: a limit of 50
  // must stop it (IDA's own limit does not apply in one-step mode).
  auto cfg = config_of(make_paper_cell());
  cfg.solver.max_steps = 50;
  cfg.solver.crawl_window_steps = 1L << 40;
  try {
    run_current_profile(cfg, {0.0, 4000.0}, {2.3, 2.3}, 2.0, 4.0);
    FAIL() << "no failure";
  } catch (const RuntimeFailure& e) {
    EXPECT_NE(std::string(e.what()).find("solver step limit: 50 internal steps"), std::string::npos) << e.what();
  }
  cfg.solver.max_steps = 200000;
  EXPECT_NO_THROW(run_current_profile(cfg, {0.0, 4000.0}, {2.3, 2.3}, 2.0, 4.0));
}

TEST(SolverLimits, WallClockLimit) {
  auto cfg = config_of(make_paper_cell());
  cfg.solver.max_wall_s = 0.0;
  try {
    run_current_profile(cfg, {0.0, 4000.0}, {2.3, 2.3}, 2.0, 4.0);
    FAIL() << "no failure";
  } catch (const RuntimeFailure& e) {
    EXPECT_NE(std::string(e.what()).find("solver wall-clock limit"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace bms
