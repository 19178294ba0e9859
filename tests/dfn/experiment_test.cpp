// Experiment strings (PyBaMM's wording) and the streamed cycler: the paper's cccv written as a
// string runs the same model as the named protocol, sample for sample; a rest and a timed step
// end on time; bad steps are input errors naming the step.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "cell/paper_cell.hpp"
#include "io/input_error.hpp"
#include "sim/cycler.hpp"
#include "sim/experiment.hpp"

namespace bms {
namespace {

class Collect : public SampleSink {
 public:
  void on_sample(const SampleRecord& s) override { samples.push_back(s); }
  void on_cycle(const CycleSummary& c) override { cycles.push_back(c); }
  std::vector<SampleRecord> samples;
  std::vector<CycleSummary> cycles;
};

SimulationConfig coarse_paper(double dt_s) {
  SimulationConfig cfg;
  cfg.cell = make_paper_cell();
  cfg.mesh = {8, 5, 8, 8};
  cfg.dt_s = dt_s;
  cfg.temperature_k = cfg.cell.thermal.ambient_temperature_k;
  cfg.ic = default_initial_conditions(cfg.cell);
  return cfg;
}

TEST(Experiment, ParsesPyBammWording) {
  const Experiment e = parse_experiment(
      "Discharge at 1C until 2.0 V; Rest for 30 minutes; Charge at 2.5 A until 3.6V; Hold at 3.6 V until 50 mA;"
      " Discharge at C/2 for 1 hour or until 2.5 V; Rest for 600 s",
      2.3, 3);
  ASSERT_EQ(e.steps.size(), 6u);
  EXPECT_EQ(e.cycles, 3);
  EXPECT_EQ(e.steps[0].mode, Mode::cc_discharge);
  EXPECT_DOUBLE_EQ(e.steps[0].value, 2.3);
  EXPECT_DOUBLE_EQ(e.steps[0].until_voltage_v, 2.0);
  EXPECT_EQ(e.steps[1].mode, Mode::rest);
  EXPECT_DOUBLE_EQ(e.steps[1].duration_s, 1800.0);
  EXPECT_EQ(e.steps[2].mode, Mode::cc_charge);
  EXPECT_DOUBLE_EQ(e.steps[2].value, -2.5);
  EXPECT_EQ(e.steps[3].mode, Mode::cv_charge);
  EXPECT_EQ(e.steps[3].kind, ControlKind::voltage);
  EXPECT_DOUBLE_EQ(e.steps[3].until_abs_current_a, 0.05);
  EXPECT_DOUBLE_EQ(e.steps[4].value, 1.15);
  EXPECT_DOUBLE_EQ(e.steps[4].duration_s, 3600.0);
  EXPECT_DOUBLE_EQ(e.steps[4].until_voltage_v, 2.5);
  EXPECT_DOUBLE_EQ(e.steps[5].duration_s, 600.0);
  // A hold after a discharge is a CV discharge.
  EXPECT_EQ(parse_experiment("Discharge at 1 A until 2 V; Hold at 2 V until C/50", 2.3, 1).steps[1].mode,
            Mode::cv_discharge);
}

TEST(Experiment, BadStepsNameTheStepAndTheProblem) {
  struct Case {
    const char* text;
    const char* needle;
  };
  for (const Case c : {Case{"Discharge at 1C", "step 1 'Discharge at 1C': the step never ends"},
                       Case{"Rest for 1 hour; Dance at 1C", "step 2 'Dance at 1C': unknown step 'dance'"},
                       Case{"Discharge at 1 parsec until 2 V", "unknown unit 'parsec'"},
                       Case{"Discharge at -1 A until 2 V", "positive, finite"},
                       Case{"Hold at 3.6 V until 3.5 V", "ends at a current"},
                       Case{"Charge at 1C until 50 mA", "ends at a voltage"},
                       Case{"Rest until 3 V", "a rest ends after a duration"},
                       Case{"Discharge at 1C until 2 V;; Rest for 1 h", "step 2: empty"},
                       Case{"", "no steps"}}) {
    try {
      parse_experiment(c.text, 2.3, 1);
      ADD_FAILURE() << c.text << ": accepted";
    } catch (const InputError& e) {
      EXPECT_NE(std::string(e.what()).find(c.needle), std::string::npos) << e.what();
    }
  }
}

TEST(Experiment, TheCccvStringIsTheNamedProtocolSampleForSample) {
  const SimulationConfig cfg = coarse_paper(10.0);
  CccvProtocol p;
  p.cycles = 1;
  Collect named, written;
  run_experiment(cfg, cccv_experiment(p), named);
  run_experiment(cfg,
                 parse_experiment("Discharge at 2.5 A until 2.0 V; Hold at 2.0 V until 125 mA; "
                                  "Charge at 2.5 A until 3.6 V; Hold at 3.6 V until 0.125 A",
                                  cfg.cell.nominal_capacity_ah, 1),
                 written);
  ASSERT_EQ(named.samples.size(), written.samples.size());
  ASSERT_GT(named.samples.size(), 500u);
  for (size_t i = 0; i < named.samples.size(); ++i) {
    EXPECT_EQ(named.samples[i].mode, written.samples[i].mode) << i;
    EXPECT_EQ(named.samples[i].voltage_v, written.samples[i].voltage_v) << i;
  }
  ASSERT_EQ(written.cycles.size(), 1u);
  EXPECT_EQ(named.cycles[0].r_film_end_ohm_m2, written.cycles[0].r_film_end_ohm_m2);
}

TEST(Experiment, TimedStepsEndOnTimeAndARestHoldsTheCurrentAtZero) {
  const SimulationConfig cfg = coarse_paper(7.0);  // steps end between output times
  Collect c;
  const SimulationResult r = run_experiment(
      cfg, parse_experiment("Discharge at 1C for 20 minutes; Rest for 10 minutes", cfg.cell.nominal_capacity_ah, 2),
      c);
  ASSERT_EQ(r.phases.size(), 4u);
  for (const auto& ph : r.phases)
    EXPECT_NEAR(ph.t_end_s - ph.t_start_s, ph.mode == Mode::rest ? 600.0 : 1200.0, 1e-6);
  EXPECT_NEAR(r.sim_s, 3600.0, 1e-6);
  for (const auto& s : c.samples) {
    if (s.mode == Mode::rest) EXPECT_NEAR(s.current_a, 0.0, 1e-9);
    else EXPECT_NEAR(s.current_a, cfg.cell.nominal_capacity_ah, 1e-9);
  }
  // The output grid is kept across the step ends.
  for (size_t i = 1; i < c.samples.size(); ++i) EXPECT_NEAR(c.samples[i].t_s, 7.0 * static_cast<double>(i), 1e-9);
  EXPECT_EQ(c.cycles.size(), 2u);
}

TEST(Experiment, AStepWhoseEndIsAlreadyMetEndsAtOnce) {
  // Charging "until 3.0 V" from a cell resting above 3.0 V: zero duration, not six hours.
  const SimulationConfig cfg = coarse_paper(10.0);
  Collect c;
  const SimulationResult r =
      run_experiment(cfg, parse_experiment("Charge at 1 A until 3.0 V; Rest for 1 minute", 2.3, 1), c);
  ASSERT_EQ(r.phases.size(), 2u);
  EXPECT_EQ(r.phases[0].t_end_s, r.phases[0].t_start_s);
  EXPECT_NEAR(r.sim_s, 60.0, 1e-9);
}

}  // namespace
}  // namespace bms
