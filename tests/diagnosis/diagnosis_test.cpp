// Issue 7: the residual diagnosis. Unit checks of its parts, and short synthetic cases end
// to end on a coarse mesh (data and model on the same mesh, so the injected value is exact).
#include <gtest/gtest.h>

#include <cmath>

#include "cell/paper_cell.hpp"
#include "diagnosis/diagnose.hpp"
#include "diagnosis/minimise.hpp"
#include "io/input_error.hpp"
#include "sim/measurement.hpp"

namespace {

using namespace bms::diagnosis;

TEST(Minimise, FindsTheGlobalMinimumPastASideMinimum) {
  // Side minimum near 0.8, global at 0.25.
  auto f = [](double x) { return std::min((x - 0.25) * (x - 0.25), 0.05 + (x - 0.8) * (x - 0.8)); };
  const auto m = minimise_bounded(f, 0.0, 1.0, 1e-4);
  EXPECT_NEAR(m.x, 0.25, 2e-4);
  EXPECT_LT(m.evaluations, 40);
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

// A few minutes of paper-cell data made by the truth model with one effect, on a coarse mesh.
class Synthetic : public ::testing::Test {
 protected:
  static constexpr bms::DfnMesh kMesh{6, 6, 6, 6};

  static Record make_data(const bms::ModelEffects& effects, bool constant) {
    std::vector<double> t, i;
    for (int k = 0; k <= 900; ++k) {
      t.push_back(k);
      double cur = 2.5;
      if (!constant) cur = k < 60 ? 0.0 : k < 420 ? 2.5 : k < 480 ? 0.0 : k < 840 ? -2.5 : 0.0;
      i.push_back(cur);
    }
    bms::SimulationConfig cfg;
    cfg.cell = bms::make_paper_cell();
    cfg.mesh = kMesh;
    cfg.ic = bms::default_initial_conditions(cfg.cell);
    cfg.effects = effects;
    const auto r = bms::run_current_profile(cfg, t, i, 1.0, 5.0);
    std::vector<double> v;
    for (const auto& s : r.samples) v.push_back(s.voltage_v);
    EXPECT_EQ(v.size(), t.size());
    return make_record("synthetic", t, i, v);
  }

  static DiagnoseSettings settings(std::vector<Effect> candidates) {
    DiagnoseSettings s;
    s.search_mesh = kMesh;
    s.final_mesh = kMesh;
    s.candidates = std::move(candidates);
    return s;
  }
};

TEST_F(Synthetic, NamesAContactResistanceAndItsSize) {
  bms::ModelEffects fx;
  fx.contact_resistance_ohm = 2e-3;
  const std::vector<Record> data{make_data(fx, false)};
  const auto r = diagnose(bms::make_paper_cell(), data,
                          settings({Effect::contact_resistance, Effect::hysteresis, Effect::current_offset}));
  EXPECT_EQ(r.selection.effect, Effect::contact_resistance) << r.selection.reason;
  EXPECT_NEAR(r.selection.value, 2e-3, 0.2 * 2e-3);
  EXPECT_GT(r.rmse_before_mv, 1.0);
  EXPECT_LE(r.rmse_after_mv, 0.2 * r.rmse_before_mv);
}

TEST_F(Synthetic, AnswersNoneWithoutAnEffect) {
  const std::vector<Record> data{make_data({}, false)};
  const auto r = diagnose(bms::make_paper_cell(), data, settings({Effect::contact_resistance, Effect::current_offset}));
  EXPECT_EQ(r.selection.effect, Effect::none) << r.selection.reason;
  EXPECT_DOUBLE_EQ(r.rmse_after_mv, r.rmse_before_mv);
}

TEST_F(Synthetic, DoesNotGuessFromOneConstantCurrent) {
  bms::ModelEffects fx;
  fx.contact_resistance_ohm = 2e-3;
  const std::vector<Record> data{make_data(fx, true)};
  const auto r = diagnose(bms::make_paper_cell(), data, settings({Effect::contact_resistance, Effect::hysteresis}));
  EXPECT_EQ(r.selection.effect, Effect::none) << r.selection.reason;
  EXPECT_NE(r.selection.reason.find("constant current"), std::string::npos) << r.selection.reason;
  EXPECT_FALSE(r.excitation_note.empty());
}

}  // namespace
