// The residual diagnosis. Unit checks of its parts, and short synthetic cases end
// to end on a coarse mesh (data and model on the same mesh, so the injected value is exact).
#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <initializer_list>
#include <stdexcept>
#include <cstdio>
#include <random>

#include "cell/paper_cell.hpp"
#include "diagnosis/adequacy.hpp"
#include "diagnosis/diagnose.hpp"
#include "diagnosis/minimise.hpp"
#include "diagnosis/parallel.hpp"
#include "io/input_error.hpp"
#include "sim/cell_catalog.hpp"
#include "sim/measurement.hpp"

namespace {

using namespace bms::diagnosis;

// The measurement noise from the voltage's second differences where the current is flat, and
// the file's resolution where it never is (a ramp at every sample: not zero).
TEST(MeasurementNoise, FlatStretchesGiveTheNoiseARampGivesTheResolution) {
  Record flat, ramp;
  std::mt19937 rng(7);
  std::normal_distribution<double> noise(0.0, 0.5e-3);
  for (int k = 0; k < 4000; ++k) {
    flat.t_s.push_back(k);
    flat.current_a.push_back(k < 2000 ? 1.0 : -1.0);
    flat.voltage_v.push_back(3.7 - 1e-5 * k + noise(rng));
    ramp.t_s.push_back(k);
    ramp.current_a.push_back(0.5 + 0.1 * std::sin(0.3 * k));  // changes 3 % of its peak per sample
    ramp.voltage_v.push_back(std::round((3.7 - 0.05 * ramp.current_a.back()) / 1e-3) * 1e-3);  // 1 mV steps
  }
  EXPECT_NEAR(measurement_noise_mv(flat), 0.5, 0.05);
  EXPECT_NEAR(measurement_noise_mv(ramp), 1.0 / std::sqrt(12.0), 1e-9) << "the 1 mV resolution, not 0";
}

TEST(Minimise, FindsTheGlobalMinimumPastASideMinimum) {
  // Side minimum near 0.8, global at 0.25.
  auto f = [](double x) { return std::min((x - 0.25) * (x - 0.25), 0.05 + (x - 0.8) * (x - 0.8)); };
  const auto m = minimise_bounded(f, 0.0, 1.0, 1e-4);
  EXPECT_NEAR(m.x, 0.25, 2e-4);
  EXPECT_LT(m.evaluations, 40);
}

TEST(Parallel, RunsEveryTaskOnceAndRethrowsOnTheCaller) {
  for (int threads : {1, 2, 3}) {
    std::vector<std::atomic<int>> hits(50);
    parallel_for(hits.size(), threads, [&](std::size_t k) { ++hits[k]; });
    for (const auto& h : hits) EXPECT_EQ(h.load(), 1) << threads << " threads";
    EXPECT_THROW(parallel_for(8, threads,
                              [](std::size_t k) {
                                if (k == 3) throw std::runtime_error("task 3");
                              }),
                 std::runtime_error);
  }
}

TEST(Selection, ChoosesAClearWinner) {
  const auto s = select_effect(10.0, {{Effect::contact_resistance, true, 1e-3, 1.0}, {Effect::hysteresis, true, 0.01, 6.0}});
  EXPECT_EQ(s.effect, Effect::contact_resistance);
  EXPECT_DOUBLE_EQ(s.value, 1e-3);
}

TEST(Selection, NoneWhenTheGainIsSmall) {
  const auto s = select_effect(10.0, {{Effect::contact_resistance, true, 1e-3, 9.0}});
  EXPECT_EQ(s.effect, Effect::none);
  EXPECT_NE(s.reason.find("meaningfully"), std::string::npos);
}

TEST(Selection, NoneWhenTwoEffectsTie) {
  const auto s = select_effect(10.0, {{Effect::current_offset, true, 0.01, 2.0}, {Effect::current_gain, true, 0.01, 2.3}});
  EXPECT_EQ(s.effect, Effect::none);
  EXPECT_NE(s.reason.find("not identifiable"), std::string::npos);
}

TEST(Selection, DecidesOnWhatIsLeftNotOnWhatIsGained) {
  // A CCCV record with a contact resistance: both candidates remove most of a 6.9 mV residual
  // (gains within 10 % of each other), but contact leaves 0.06 mV above the 0.197 mV floor and
  // conductivity 0.31 mV: not a tie.
  SelectionRules rules;
  rules.floor_mv = 0.197;
  const auto s = select_effect(6.93, {{Effect::contact_resistance, true, 3e-3, 0.206}, {Effect::conductivity, true, 0.9, 0.367}},
                               rules);
  EXPECT_EQ(s.effect, Effect::contact_resistance) << s.reason;
}

TEST(Selection, TiesWhenBothLeaveTheSameAboveTheFloor) {
  SelectionRules rules;
  rules.floor_mv = 0.2;
  // Both at the floor: nothing in the data separates them.
  const auto at_floor = select_effect(6.0, {{Effect::contact_resistance, true, 3e-3, 0.205}, {Effect::hysteresis, true, 0.01, 0.215}},
                                      rules);
  EXPECT_EQ(at_floor.effect, Effect::none);
  EXPECT_FALSE(at_floor.identifiable);
  // Both well above it, within a quarter of each other.
  const auto above = select_effect(6.0, {{Effect::contact_resistance, true, 3e-3, 1.0}, {Effect::hysteresis, true, 0.01, 1.2}},
                                   rules);
  EXPECT_FALSE(above.identifiable) << above.reason;
}

TEST(Selection, NoneForConfoundedTwinsAtConstantCurrent) {
  SelectionRules rules;
  rules.constant_current_only = true;
  const std::vector<CandidateScore> c{{Effect::contact_resistance, true, 1e-3, 1.0}, {Effect::hysteresis, true, 0.01, 5.0}};
  EXPECT_EQ(select_effect(10.0, c, rules).effect, Effect::none);
  EXPECT_EQ(select_effect(10.0, c).effect, Effect::contact_resistance);
}

TEST(Selection, UnavailableCandidatesAreIgnored) {
  const auto s = select_effect(10.0, {{Effect::thermal, false, 0.0, 0.0}, {Effect::hysteresis, true, 0.01, 1.0}});
  EXPECT_EQ(s.effect, Effect::hysteresis);
}

TEST(Split, BlocksAlternateAndCoverEverySample) {
  std::vector<char> train, validate;
  split_samples(1000, 8, train, validate);
  std::size_t nt = 0;
  for (std::size_t k = 0; k < 1000; ++k) {
    EXPECT_NE(train[k], validate[k]);
    nt += train[k] ? 1 : 0;
  }
  EXPECT_EQ(nt, 500u);
  EXPECT_TRUE(train[0]);
  EXPECT_TRUE(validate[999]);
}

TEST(Effects, DrivingCurrentUndoesTheSensorModel) {
  std::vector<bms::SampleRecord> truth(3);
  const double currents[] = {2.5, 0.0, -1.2};
  for (int k = 0; k < 3; ++k) truth[static_cast<std::size_t>(k)].current_a = currents[k];
  bms::MeasurementModel m;
  m.current_offset_a = 0.01;
  const auto off = bms::measure(truth, m);
  const auto back = driving_current({Effect::current_offset, 0.01}, off.current_a);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(back[static_cast<std::size_t>(k)], currents[k], 1e-12);
  m.current_offset_a = 0.0;
  m.current_gain = 0.01;
  const auto gain = bms::measure(truth, m);
  const auto back2 = driving_current({Effect::current_gain, 0.01}, gain.current_a);
  for (int k = 0; k < 3; ++k) EXPECT_NEAR(back2[static_cast<std::size_t>(k)], currents[k], 1e-12);
}

TEST(Records, RejectTooShortAndNonMonotonic) {
  std::vector<double> t, i, v;
  for (int k = 0; k < 20; ++k) {
    t.push_back(k);
    i.push_back(1.0);
    v.push_back(3.3);
  }
  EXPECT_THROW(make_record("short.csv", t, i, v), bms::InputError);
  for (int k = 20; k < 100; ++k) {
    t.push_back(k);
    i.push_back(1.0);
    v.push_back(3.3);
  }
  EXPECT_NO_THROW(make_record("ok.csv", t, i, v));
  t[50] = t[49];
  EXPECT_THROW(make_record("repeat.csv", t, i, v), bms::InputError);
}

TEST(Excitation, TellsConstantCurrentFromACycle) {
  std::vector<double> t, i, v;
  for (int k = 0; k < 200; ++k) {
    t.push_back(k);
    i.push_back(k == 0 ? 0.0 : 2.0);
    v.push_back(3.3);
  }
  const auto cc = analyse_excitation(make_record("cc", t, i, v));
  EXPECT_TRUE(cc.constant_current_only);
  for (int k = 100; k < 200; ++k) i[static_cast<std::size_t>(k)] = -1.0;
  const auto cyc = analyse_excitation(make_record("cyc", t, i, v));
  EXPECT_FALSE(cyc.constant_current_only);
  EXPECT_TRUE(cyc.has_charge && cyc.has_discharge);
  const auto rest = analyse_excitation(make_record("rest", t, std::vector<double>(200, 0.0), v));
  EXPECT_TRUE(rest.no_current);
}

// A few minutes of paper-cell data made by the truth model with one effect. No inverse crime:
// the data come from a finer mesh and a tighter tolerance than the fitting model, with
// voltage noise; the diagnosis fits on a coarse search mesh and scores on a finer one.
enum class Shape { constant, cycle_with_rests, cccv_without_rests, rest_pulse, drive_cycle };

const char* shape_name(Shape s) {
  switch (s) {
    case Shape::constant: return "constant";
    case Shape::cycle_with_rests: return "cycle_with_rests";
    case Shape::cccv_without_rests: return "cccv_without_rests";
    case Shape::rest_pulse: return "rest_pulse";
    case Shape::drive_cycle: return "drive_cycle";
  }
  return "?";
}

class Synthetic : public ::testing::Test {
 protected:
  static constexpr bms::DfnMesh kDataMesh{12, 12, 12, 12};
  static constexpr bms::DfnMesh kSearchMesh{5, 5, 5, 5};
  static constexpr bms::DfnMesh kFinalMesh{8, 8, 8, 8};
  static constexpr double kNoiseV = 5e-5;  // 0.05 mV: a good cycler's voltage channel

  // The current of one 900 s record at 1 s of each shape, positive = discharge.
  static double profile_current_a(Shape shape, int k, double amplitude_a) {
    switch (shape) {
      case Shape::constant: return amplitude_a;
      case Shape::cycle_with_rests:
        return k < 60 ? 0.0 : k < 420 ? amplitude_a : k < 480 ? 0.0 : k < 840 ? -amplitude_a : 0.0;
      case Shape::cccv_without_rests:
        // Discharge, charge, then the current of a constant-voltage hold decaying towards its
        // cut-off: never at rest.
        return k < 360 ? amplitude_a : k < 660 ? -amplitude_a : -amplitude_a * std::exp(-(k - 660) / 80.0);
      case Shape::rest_pulse: {
        // Rest, then 30 s discharge pulse, 30 s rest, 30 s charge pulse at 3/4, 30 s rest.
        const int phase = (k - 60) % 120;
        return k < 60 ? 0.0 : phase < 30 ? amplitude_a : phase < 60 ? 0.0 : phase < 90 ? -0.75 * amplitude_a : 0.0;
      }
      case Shape::drive_cycle: {
        // A drive-like current: acceleration peaks, cruising, and regenerative braking (charge).
        const double x = 2.0 * M_PI * k;
        return amplitude_a * (0.35 + 0.5 * std::sin(x / 97.0) + 0.35 * std::sin(x / 31.0 + 1.0) +
                              0.2 * std::sin(x / 11.0 + 2.0));
      }
    }
    return 0.0;
  }
  static std::vector<double> cycle_current(Shape shape, std::vector<double>& t, double amplitude_a = 2.5) {
    std::vector<double> i;
    for (int k = 0; k <= 900; ++k) {
      t.push_back(k);
      i.push_back(profile_current_a(shape, k, amplitude_a));
    }
    return i;
  }
  static std::vector<double> cycle_current(bool constant, std::vector<double>& t, double amplitude_a = 2.5) {
    return cycle_current(constant ? Shape::constant : Shape::cycle_with_rests, t, amplitude_a);
  }

  static Record make_data(const bms::ModelEffects& effects, bool constant, const bms::CellParameters& cell,
                          double amplitude_a = 2.5, double depth_ah = 0.0, unsigned seed = 1) {
    return make_data(effects, constant ? Shape::constant : Shape::cycle_with_rests, cell, amplitude_a, depth_ah, seed);
  }
  static Record make_data(const bms::ModelEffects& effects, Shape shape, const bms::CellParameters& cell,
                          double amplitude_a = 2.5, double depth_ah = 0.0, unsigned seed = 1) {
    std::vector<double> t;
    const std::vector<double> i = cycle_current(shape, t, amplitude_a);
    bms::SimulationConfig cfg;
    cfg.cell = cell;
    cfg.mesh = kDataMesh;
    cfg.solver.rtol = 1e-8;
    cfg.ic = depth_ah > 0 ? initial_state_at_depth(cfg.cell, depth_ah) : bms::default_initial_conditions(cfg.cell);
    cfg.effects = effects;
    const auto r = bms::run_current_profile(cfg, t, i, 1.0, 5.0);
    std::mt19937 rng(seed);
    std::normal_distribution<double> noise(0.0, kNoiseV);
    std::vector<double> v;
    for (const auto& s : r.samples) v.push_back(s.voltage_v + noise(rng));
    EXPECT_EQ(v.size(), t.size()) << r.note;
    Record rec = make_record("synthetic", t, i, v);
    if (depth_ah > 0) rec.initial_depth_ah = depth_ah;  // a known start, as --initial-soc gives
    return rec;
  }
  static Record make_data(const bms::ModelEffects& effects, bool constant) {
    return make_data(effects, constant, bms::make_paper_cell());
  }

  static DiagnoseSettings settings(std::vector<Effect> candidates) {
    DiagnoseSettings s;
    s.search_mesh = kSearchMesh;
    s.final_mesh = kFinalMesh;
    s.candidates = std::move(candidates);
    return s;
  }
  static DiagnoseSettings all_candidates() {
    return settings({std::begin(kAllCandidates), std::end(kAllCandidates)});
  }
};

// The decision on each listed effect, now against every candidate of the wider
// space: the right name, its size within 20 %, and the held-out residual cut to 20 %.
struct ListedCase {
  Effect effect;
  double value;
  double amplitude_a = 2.5;
  Shape shape = Shape::cycle_with_rests;
};

class ListedEffect : public Synthetic, public ::testing::WithParamInterface<ListedCase> {};

TEST_P(ListedEffect, IsNamedWithItsSizeAgainstEveryCandidate) {
  const ListedCase c = GetParam();
  bms::ModelEffects fx;
  if (!set_model_effect(fx, {c.effect, c.value})) GTEST_SKIP() << "not in this build's truth model";
  Record data = make_data(fx, c.shape, bms::make_paper_cell(), c.amplitude_a);
  if (c.effect == Effect::current_offset || c.effect == Effect::current_gain) {
    // The sensor reads the true current wrongly: the data's current column is the reading.
    for (auto& x : data.current_a) x = c.effect == Effect::current_offset ? x + c.value : x * (1.0 + c.value);
  }
  const auto r = diagnose(bms::make_paper_cell(), {data}, all_candidates());
  EXPECT_EQ(r.answer, c.effect) << r.reason;
  EXPECT_TRUE(r.explained) << r.reason;
  ASSERT_FALSE(r.model.empty()) << r.reason;
  EXPECT_NEAR(knob_value(r.model, c.effect), c.value, 0.2 * std::abs(c.value)) << r.reason;
  EXPECT_LE(r.heldout_after_mv, 0.2 * r.heldout_before_mv);
}

INSTANTIATE_TEST_SUITE_P(Synthetic, ListedEffect,
                         ::testing::Values(ListedCase{Effect::contact_resistance, 2e-3},
                                           ListedCase{Effect::hysteresis, 0.015},
                                           ListedCase{Effect::current_offset, 0.02},
                                           ListedCase{Effect::current_gain, 0.03},
                                           ListedCase{Effect::thermal, 0.05, 5.0}),
                         [](const auto& p) { return std::string(effect_name(p.param.effect)); });

// The same effects on records without the rests the selection used to lean on: a CCCV
// record (discharge, charge, constant-voltage taper), a rest-pulse record and a drive cycle.
std::vector<ListedCase> listed_on_shapes(std::initializer_list<Shape> shapes) {
  std::vector<ListedCase> cases;
  for (Shape shape : shapes) {
    cases.push_back({Effect::contact_resistance, 3e-3, 2.5, shape});
    cases.push_back({Effect::hysteresis, 0.015, 2.5, shape});
    cases.push_back({Effect::current_offset, 0.02, 2.5, shape});
    cases.push_back({Effect::current_gain, 0.03, 2.5, shape});
    cases.push_back({Effect::thermal, 0.05, 5.0, shape});
  }
  return cases;
}

std::string shape_case_name(const ::testing::TestParamInfo<ListedCase>& p) {
  return std::string(shape_name(p.param.shape)) + "_" + effect_name(p.param.effect);
}

INSTANTIATE_TEST_SUITE_P(Shapes, ListedEffect,
                         ::testing::ValuesIn(listed_on_shapes({Shape::cccv_without_rests, Shape::rest_pulse})),
                         shape_case_name);

// The drive cycle: 9-15 s a case (every candidate re-fitted over a current that never repeats).
INSTANTIATE_TEST_SUITE_P(DriveCycle, ListedEffect, ::testing::ValuesIn(listed_on_shapes({Shape::drive_cycle})),
                         shape_case_name);

TEST_F(Synthetic, AnswersNoneWithoutAnEffect) {
  const std::vector<Record> data{make_data({}, false)};
  const auto r = diagnose(bms::make_paper_cell(), data, all_candidates());
  EXPECT_EQ(r.answer, Effect::none) << r.reason;
  EXPECT_TRUE(r.at_floor_before) << r.reason;
  EXPECT_TRUE(r.effects.empty());
}

// The candidates, the forward selection and the sensitivities run on several threads: the
// answer and every number must be the same on one thread and on two (every candidate of
// `all` competes; a current-sensor gain, whose knob changes the drive and needs model runs).
TEST_F(Synthetic, SameAnswerAndNumbersOnOneAndTwoThreads) {
  std::vector<Record> data{make_data({}, Shape::rest_pulse, bms::make_paper_cell())};
  for (auto& x : data.front().current_a) x *= 1.03;  // the sensor reads 3 % high
  DiagnoseSettings one = all_candidates(), two = one;
  one.threads = 1;
  two.threads = 2;
  const auto a = diagnose(bms::make_paper_cell(), data, one);
  const auto b = diagnose(bms::make_paper_cell(), data, two);
  EXPECT_EQ(a.answer, b.answer) << a.reason << " | " << b.reason;
  EXPECT_EQ(a.reason, b.reason);
  EXPECT_EQ(a.effects, b.effects);
  ASSERT_EQ(a.model.size(), b.model.size());
  for (std::size_t k = 0; k < a.model.size(); ++k) {
    EXPECT_EQ(a.model[k].effect, b.model[k].effect);
    EXPECT_EQ(a.model[k].value, b.model[k].value);
  }
  EXPECT_EQ(a.heldout_after_mv, b.heldout_after_mv);
  EXPECT_EQ(a.rmse_after_mv, b.rmse_after_mv);
  ASSERT_EQ(a.candidates.size(), b.candidates.size());
  for (std::size_t k = 0; k < a.candidates.size(); ++k) {
    EXPECT_EQ(a.candidates[k].effect, b.candidates[k].effect);
    EXPECT_EQ(a.candidates[k].value, b.candidates[k].value);
    EXPECT_EQ(a.candidates[k].heldout_rmse_mv, b.candidates[k].heldout_rmse_mv);
    EXPECT_EQ(a.candidates[k].evaluations, b.candidates[k].evaluations);
  }
  ASSERT_EQ(a.steps.size(), b.steps.size());
  for (std::size_t k = 0; k < a.steps.size(); ++k) EXPECT_EQ(a.steps[k].scores, b.steps[k].scores);
  ASSERT_EQ(a.identifiability.size(), b.identifiability.size());
  for (std::size_t k = 0; k < a.identifiability.size(); ++k)
    EXPECT_EQ(a.identifiability[k].sensitivity_mv, b.identifiability[k].sensitivity_mv);
  EXPECT_EQ(a.answer, Effect::current_gain) << a.reason;
  EXPECT_NEAR(knob_value(a.model, Effect::current_gain), 0.03, 0.2 * 0.03) << a.reason;
  // A knob that needs model runs is fitted by Gauss-Newton in a few runs, not by a 20-point
  // line search.
  for (const auto& c : a.candidates) {
    if (c.effect == Effect::current_gain || c.effect == Effect::contact_resistance) {
      EXPECT_LE(c.evaluations, 8) << effect_name(c.effect);
    }
  }
}

TEST_F(Synthetic, DoesNotGuessFromOneConstantCurrent) {
  bms::ModelEffects fx;
  fx.contact_resistance_ohm = 2e-3;
  const std::vector<Record> data{make_data(fx, true)};
  const auto r = diagnose(bms::make_paper_cell(), data, settings({Effect::contact_resistance, Effect::hysteresis}));
  EXPECT_NE(r.answer, Effect::contact_resistance) << r.reason;
  EXPECT_NE(r.answer, Effect::hysteresis) << r.reason;
  EXPECT_FALSE(r.explained);
  EXPECT_NE(r.reason.find("constant current"), std::string::npos) << r.reason;
  EXPECT_FALSE(r.excitation_note.empty());
}

// Off-list honesty: effects the tool has no candidate for. Either the residual is explained
// to 20 % (by something equivalent) or the answer is `unexplained`; never a name with most of
// the residual left.
void expect_honest(const DiagnosisResult& r) {
  if (r.explained) {
    EXPECT_LE(r.heldout_after_mv, 0.2 * r.heldout_before_mv) << r.reason;
    EXPECT_NE(r.answer, Effect::none);
  } else {
    EXPECT_EQ(r.answer, Effect::unexplained) << r.reason;
    EXPECT_TRUE(r.effects.empty());
    EXPECT_TRUE(r.model.empty());
  }
  std::printf("answer %s, held-out %.3f -> %.3f mV: %s\n", effect_name(r.answer), r.heldout_before_mv,
              r.explained ? r.heldout_after_mv : r.best_partial_heldout_mv, r.reason.substr(0, 300).c_str());
}

TEST_F(Synthetic, OffListParticleSizeSpreadIsExplainedOrUnexplained) {
  bms::ModelEffects fx;
  fx.particle_size_sigma = 0.5;
  const auto r = diagnose(bms::make_paper_cell(), {make_data(fx, false)}, all_candidates());
  EXPECT_GT(r.heldout_before_mv, 1.0);
  expect_honest(r);
}

TEST_F(Synthetic, OffListSlowCathodeDiffusionIsExplainedOrUnexplained) {
  // The About:Energy LFP cell, whose cathode diffusion shows at 1C, with the diffusivity at
  // 0.3x; only the listed (sensor and wiring) effects are candidates.
  const bms::CellParameters nominal = bms::load_cell("aboutenergy");
  bms::CellParameters cell = nominal;
  cell.positive.solid_diffusivity_m2_s *= 0.3;
  const auto r = diagnose(nominal, {make_data({}, false, cell, 2.0, 0.5)},
                          settings({std::begin(kListedCandidates), std::end(kListedCandidates)}));
  EXPECT_GT(r.heldout_before_mv, 1.0);
  expect_honest(r);
}

TEST_F(Synthetic, OffListAnodeParticleSizeSpreadIsExplainedOrUnexplained) {
  // The About:Energy cell without its side reaction (the side reaction excludes an anode
  // distribution).
  bms::ModelEffects fx;
  fx.particle_size_negative_sigma = 0.5;
  bms::CellParameters cell = bms::load_cell("aboutenergy");
  cell.side.enabled = false;
  const auto r = diagnose(cell, {make_data(fx, false, cell, 4.0, 0.5)}, all_candidates());
  EXPECT_GT(r.heldout_before_mv, 1.0);
  expect_honest(r);
}

// A cathode whose diffusivity falls towards full lithiation (About:Energy cell, 100x slower at
// x = 1 from a knee at 0.6), a record deep in the discharge where the cathode is past its knee:
// the profile candidate explains the residual and a constant diffusivity factor does not.
TEST_F(Synthetic, DiffusivityProfileIsFoundAndAConstantFactorIsNotEnough) {
  bms::CellParameters cell = bms::load_cell("aboutenergy");
  bms::ModelEffects fx;
  fx.diffusivity_profile_positive = -2.0;
  fx.diffusivity_profile_positive_knee = 0.6;
  const Record data = make_data(fx, false, cell, 2.0, 1.2);
  const auto r = diagnose(cell, {data}, settings({Effect::diffusivity_profile_positive, Effect::diffusivity_positive}));
  std::printf("answer %s, held-out %.3f -> %.3f mV, profile %.3f knee %.3f: %s\n", effect_name(r.answer),
              r.heldout_before_mv, r.heldout_after_mv, knob_value(r.model, Effect::diffusivity_profile_positive),
              knob_value(r.model, Effect::diffusivity_profile_knee), r.reason.substr(0, 300).c_str());
  double profile_mv = 0.0, constant_mv = 0.0;
  for (const auto& c : r.candidates) {
    std::printf("  %s %.3f mV\n", effect_name(c.effect), c.heldout_rmse_mv);
    if (c.effect == Effect::diffusivity_profile_positive) profile_mv = c.heldout_rmse_mv;
    if (c.effect == Effect::diffusivity_positive) constant_mv = c.heldout_rmse_mv;
  }
  EXPECT_GT(r.heldout_before_mv, 1.0);
  EXPECT_LT(profile_mv, 0.75 * constant_mv);  // alone, the profile leaves less than a constant factor
  EXPECT_EQ(r.answer, Effect::diffusivity_profile_positive) << r.reason;
  EXPECT_TRUE(r.explained) << r.reason;
  EXPECT_LE(r.heldout_after_mv, 0.2 * r.heldout_before_mv);
  EXPECT_NEAR(knob_value(r.model, Effect::diffusivity_profile_knee), 0.6, 0.05);
}

// A cathode whose reaction resistance rises as its particles fill (About:Energy cell, 0.05 ohm m2
// below a knee at 0.6, 316x at x = 1), the record deep in the discharge: the resistive reactant
// is named with its size, and neither a contact resistance (the same drop everywhere) nor the
// diffusivity profile (a rate-dependent knee) explains it.
TEST_F(Synthetic, ResistiveReactantIsFoundAgainstContactAndProfile) {
  bms::CellParameters cell = bms::load_cell("aboutenergy");
  bms::ModelEffects fx;
  fx.resistive_reactant_positive_ohm_m2 = 0.05;
  fx.resistive_reactant_positive_log10 = 2.5;
  fx.resistive_reactant_positive_knee = 0.6;
  const Record data = make_data(fx, false, cell, 2.0, 1.2);
  const auto r = diagnose(cell, {data},
                          settings({Effect::resistive_reactant_positive, Effect::contact_resistance,
                                    Effect::diffusivity_profile_positive}));
  std::printf("answer %s, held-out %.3f -> %.3f mV, R %.4g ohm m2, rise %.3f, knee %.3f: %s\n", effect_name(r.answer),
              r.heldout_before_mv, r.heldout_after_mv, knob_value(r.model, Effect::resistive_reactant_positive),
              knob_value(r.model, Effect::resistive_reactant_log10), knob_value(r.model, Effect::resistive_reactant_knee),
              r.reason.substr(0, 300).c_str());
  for (const auto& c : r.candidates) std::printf("  %s %.3f mV\n", effect_name(c.effect), c.heldout_rmse_mv);
  EXPECT_GT(r.heldout_before_mv, 1.0);
  EXPECT_EQ(r.answer, Effect::resistive_reactant_positive) << r.reason;
  EXPECT_TRUE(r.explained) << r.reason;
  EXPECT_LE(r.heldout_after_mv, 0.2 * r.heldout_before_mv);
  // The resistance where the record ends (x about 0.9): within 20 % of the truth's.
  const auto resistance_at = [](double r0, double rise, double knee, double x) {
    return r0 * std::pow(10.0, rise * std::clamp((x - knee) / (1.0 - knee), 0.0, 1.0));
  };
  const double truth = resistance_at(0.05, 2.5, 0.6, 0.9);
  EXPECT_NEAR(resistance_at(knob_value(r.model, Effect::resistive_reactant_positive),
                            knob_value(r.model, Effect::resistive_reactant_log10),
                            knob_value(r.model, Effect::resistive_reactant_knee), 0.9),
              truth, 0.2 * truth);
}

TEST_F(Synthetic, OffListHysteresisAndContactTogetherAreNotOneName) {
  // Two listed effects at once, only one candidate allowed: the single name would leave a
  // large part of the residual.
  bms::ModelEffects fx;
  fx.contact_resistance_ohm = 3e-3;
  fx.hysteresis_v = 0.015;
  const auto r = diagnose(bms::make_paper_cell(), {make_data(fx, false)},
                          settings({Effect::contact_resistance, Effect::current_gain}));
  EXPECT_GT(r.heldout_before_mv, 1.0);
  expect_honest(r);
}

}  // namespace
