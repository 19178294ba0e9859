// The stated parameter spread's voltage 1-sigma (ReducedCell::spread_voltage_sd_v) and its film
// equivalent in the identifier path's sd (IdentifierFilmPath::Config::spread).
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstring>

#include "bms/fw/estimation/identifier_film_path.hpp"
#include "bms/fw/model/reduced_cell.hpp"
#include "film_path_learning.hpp"

namespace {

namespace fw = bms::fw;
using Model = fw::ReducedCell<double>;
using Spread = fw::StatedSpread<double>;

constexpr double kChargeA = -2.5;  // 1C charge
constexpr double kFilmOhmM2 = 3.391e-3;
constexpr double kDtS = 0.2;

// The paper cell with the anode's exchange current at (1 - s) of nominal.
template <int PerMille>
struct SlowAnodeTraits : fw::PaperCellTraits {
  static constexpr fw::paper::Electrode scaled() {
    fw::paper::Electrode e = fw::PaperCellTraits::kNeg;
    e.i0_coefficient *= 1.0 - PerMille / 1000.0;
    return e;
  }
  static constexpr fw::paper::Electrode kNeg = scaled();
};

// A nominal model after `ticks` of 1C charge from the default state, and this tick's voltage.
double charged(Model& m, int ticks) {
  m.init_default();
  double v = 0.0;
  for (int k = 0; k < ticks; ++k) v = m.step_current(kChargeA, kFilmOhmM2, kDtS).voltage_v;
  return v;
}

TEST(StatedSpread, ZeroStatedGivesZeroAndTheTermGrowsWithTheStatedSpread) {
  Model m;
  const double v = charged(m, 600);  // 2 minutes of 1C charge: 3.48 V
  EXPECT_EQ(m.spread_voltage_sd_v(kChargeA, v, Spread{}), 0.0);
  double last = 0.0;
  for (double s : {0.02, 0.05, 0.1, 0.2, 0.4}) {
    Spread sp;
    sp.anode_i0_rel = s;
    sp.cathode_i0_rel = s;
    sp.transport_rel = s;
    sp.area_rel = s;
    const double sd = m.spread_voltage_sd_v(kChargeA, v, sp);
    EXPECT_GT(sd, last) << s;
    last = sd;
  }
  // Each stated parameter alone gives a positive term.
  for (int which = 0; which < 4; ++which) {
    Spread sp;
    (which == 0 ? sp.anode_i0_rel : which == 1 ? sp.cathode_i0_rel : which == 2 ? sp.transport_rel : sp.area_rel) = 0.1;
    EXPECT_GT(m.spread_voltage_sd_v(kChargeA, v, sp), 0.0) << which;
  }
}

// On a known tick the anode term is the voltage a model whose anode exchange current is (1 - s)
// of nominal gives from the same state: the closed form is the model's own kinetics.
TEST(StatedSpread, TheAnodeKineticTermIsTheModelsResponseToASlowerAnode) {
  Model m;
  const double v = charged(m, 600);  // 2 minutes of 1C charge: 3.48 V
  Spread sp;
  sp.anode_i0_rel = 0.2;
  const double closed_v = m.spread_voltage_sd_v(kChargeA, v, sp);
  fw::ReducedCell<double, SlowAnodeTraits<200>> slow;
  slow.init_default();
  typename fw::ReducedCell<double, SlowAnodeTraits<200>>::State st{};
  static_assert(sizeof(st) == sizeof(m.state()), "same state layout");
  std::memcpy(&st, &m.state(), sizeof(st));
  ASSERT_TRUE(slow.restore(st));
  // The next tick from the same state, nominal and slow: the difference is the kinetics' share.
  const double dv = m.peek_voltage(kChargeA, kFilmOhmM2, kDtS) - slow.peek_voltage(kChargeA, kFilmOhmM2, kDtS);
  EXPECT_LT(dv, 0.0);  // a slower anode charges at a higher voltage
  EXPECT_NEAR(closed_v, std::fabs(dv), 1e-3 * std::fabs(dv));  // measured 1e-5 relative
  // And its size against the film: several times the film's own drop j_n R_film at 1C.
  const double h = m.step_current(kChargeA, kFilmOhmM2, kDtS).markov_v_per_ohm_m2;
  EXPECT_GT(closed_v / std::fabs(h), kFilmOhmM2);
}

// Each term's size at this tick for set 4's tolerances stated as 1-sigma (kinetics 30 %, transport
// 20 %, area 3 %, each / sqrt(3)), as % of the film (printed for docs/results/envelope.md): the
// kinetics' share is several films, the transport's a tenth of one.
TEST(StatedSpread, TermsAtA1CChargeTickAgainstTheFilm) {
  Model m;
  const double v = charged(m, 600);
  const double film_v = kFilmOhmM2 * m.step_current(kChargeA, kFilmOhmM2, kDtS).markov_v_per_ohm_m2;
  m.init_default();
  const double v0 = charged(m, 600);
  ASSERT_EQ(v, v0);
  const double stated[4] = {0.1732, 0.1732, 0.1155, 0.01732};
  const char* names[4] = {"anode i0", "cathode i0", "transport", "area"};
  double pct[5];
  for (int which = 0; which < 5; ++which) {
    Spread sp;
    if (which == 0 || which == 4) sp.anode_i0_rel = stated[0];
    if (which == 1 || which == 4) sp.cathode_i0_rel = stated[1];
    if (which == 2 || which == 4) sp.transport_rel = stated[2];
    if (which == 3 || which == 4) sp.area_rel = stated[3];
    pct[which] = 100.0 * m.spread_voltage_sd_v(kChargeA, v, sp) / film_v;
    std::printf("stated spread at 1C, 120 s into the charge: %s %.1f %% of the film\n",
                which < 4 ? names[which] : "all (quadrature)", pct[which]);
  }
  EXPECT_GT(pct[0], 100.0);  // the anode's kinetics alone: more than the film
  EXPECT_LT(pct[2], 0.2 * pct[0]);
  EXPECT_NEAR(pct[4] * pct[4], pct[0] * pct[0] + pct[1] * pct[1] + pct[2] * pct[2] + pct[3] * pct[3], 1e-6 * pct[4] * pct[4]);
}

// A spread of 1 or more has no 1 - s to divide by: the term is left out, not infinite.
TEST(StatedSpread, ASpreadOfOneOrMoreIsLeftOut) {
  Model m;
  const double v = charged(m, 600);
  Spread sp;
  sp.anode_i0_rel = 1.0;
  sp.transport_rel = 2.0;
  EXPECT_EQ(m.spread_voltage_sd_v(kChargeA, v, sp), 0.0);
}

// The film path's reported level with a stated spread: the inverse-variance mean of the prior and
// the fitted level (the fit's sd with the spread's term), off without a spread. A stand-in model
// gives a spread whose film equivalent is twice the film, as set 4's kinetics about do.
struct SpreadModel {
  double sd_v;
  double spread_voltage_sd_v(double /*current_a*/, double /*voltage_v*/, const Spread& /*s*/) const { return sd_v; }
};
static_assert(fw::kGivesSpread<SpreadModel, double>, "the stand-in gives a spread");

using Path = fw::IdentifierFilmPath<double>;
constexpr double kH = fw::test::kPathH;

Path::Config path_config(bool stated) {
  Path::Config c;
  c.identifier.r_film_nominal_ohm_m2 = kFilmOhmM2;
  c.identifier.growth_nominal_ohm_m2_per_a_m3_s = 1e-12;
  c.temperature_sd_k = 0.0;
  if (stated) c.spread.anode_i0_rel = 0.1732;
  return c;
}

TEST(StatedSpread, TheReportedFilmIsTheInverseVarianceMeanOfThePriorAndTheFit) {
  const double truth = 1.5 * kFilmOhmM2;
  Path fused(path_config(true), kDtS), plain(path_config(false), kDtS);
  // Before any fit the prior is held: reported as it is, with its own sd.
  EXPECT_EQ(fused.r_film_ohm_m2(), plain.r_film_ohm_m2());
  EXPECT_EQ(fused.film_sd_ohm_m2(), plain.film_sd_ohm_m2());
  const SpreadModel model{2.0 * kFilmOhmM2 * kH};
  fw::test::learn_ticks(fused, model, 200, truth);
  fw::test::learn_ticks(plain, model, 200, truth);
  ASSERT_FALSE(fused.holding());
  ASSERT_FALSE(plain.holding());
  // The spread changes what is reported, not what is fitted.
  const double fit = fused.identifier().film_ohm_m2();
  EXPECT_EQ(fit, plain.identifier().film_ohm_m2());
  EXPECT_NEAR(fit, truth, 1e-3 * truth);
  // No spread: the fit and its sd, unchanged.
  EXPECT_EQ(plain.r_film_ohm_m2(), fit);
  EXPECT_EQ(plain.film_sd_ohm_m2(), plain.fitted_sd_ohm_m2());
  // The prior is what an identifier that never learned reports at the same growth.
  const fw::FilmGrowthIdentifier<double>& id = fused.identifier();
  fw::FilmGrowthIdentifier<double> never(path_config(true).identifier);
  never.propagate(-1.0, 200 * kDtS);
  EXPECT_NEAR(id.growth_ohm_m2(), never.growth_ohm_m2(), 1e-15);
  EXPECT_NEAR(id.prior_film_ohm_m2(), never.film_ohm_m2(), 1e-15);
  EXPECT_NEAR(id.prior_film_sd_ohm_m2(), never.film_sd_ohm_m2(), 1e-9 * never.film_sd_ohm_m2());
  // The fit's sd carries the spread's film equivalent (twice the film) in quadrature.
  const double sf = fused.fitted_sd_ohm_m2(), sp = id.prior_film_sd_ohm_m2(), prior = id.prior_film_ohm_m2();
  EXPECT_NEAR(fused.film_spread_ohm_m2(), 2.0 * kFilmOhmM2, 1e-12);
  EXPECT_NEAR(sf * sf, plain.fitted_sd_ohm_m2() * plain.fitted_sd_ohm_m2() + 4.0 * kFilmOhmM2 * kFilmOhmM2, 1e-15);
  ASSERT_GT(sf, sp);  // the fit says less than the prior here
  const double wp = 1.0 / (sp * sp), wf = 1.0 / (sf * sf);
  EXPECT_NEAR(fused.r_film_ohm_m2(), (wp * prior + wf * fit) / (wp + wf), 1e-12 * fit);
  EXPECT_NEAR(fused.film_sd_ohm_m2(), 1.0 / std::sqrt(wp + wf), 1e-12 * sp);
  // Between the two, nearer the prior; sharper than either.
  EXPECT_GT(fused.r_film_ohm_m2(), prior);
  EXPECT_LT(fused.r_film_ohm_m2(), 0.5 * (prior + fit));
  EXPECT_LT(fused.film_sd_ohm_m2(), sp);
  std::printf("prior %.4g (sd %.3g), fit %.4g (sd %.3g): reported %.4g (sd %.3g) ohm m2\n", prior, sp, fit, sf,
              fused.r_film_ohm_m2(), fused.film_sd_ohm_m2());
}

}  // namespace

namespace {

// With Config::fuse_level_only the prior is combined with the fitted level alone: the prior's
// level carries the fit's growth, so the reported film grows as the fit does, not leaning to the
// nominal law as the whole film's combination does. Two charges of a truth that grew twice as
// the nominal law between them give the fit a gain of about 2.
TEST(StatedSpread, TheLevelAloneCombinedReportsTheFitsGrowth) {
  Path::Config cw = path_config(true), cl = path_config(true);
  cw.identifier.growth_nominal_ohm_m2_per_a_m3_s = cl.identifier.growth_nominal_ohm_m2_per_a_m3_s = 1e-7;
  cl.fuse_level_only = true;
  Path whole(cw, kDtS), level(cl, kDtS);
  const SpreadModel model{2.0 * kFilmOhmM2 * kH};
  const double first = 1.5 * kFilmOhmM2;
  for (Path* p : {&whole, &level}) {
    fw::test::learn_ticks(*p, model, 200, first);
    const double g0 = p->identifier().growth_ohm_m2();
    p->propagate(-1.0, 1000.0);
    fw::test::learn_ticks(*p, model, 200, first + 2.0 * (p->identifier().growth_ohm_m2() - g0));
  }
  ASSERT_FALSE(level.holding());
  const fw::FilmGrowthIdentifier<double>& id = level.identifier();
  EXPECT_EQ(id.film_ohm_m2(), whole.identifier().film_ohm_m2()) << "the option changes the report, not the fit";
  const double g = id.growth_ohm_m2(), gain = id.gain();
  ASSERT_GT(g, 0.02 * kFilmOhmM2);
  ASSERT_GT(gain, 1.3) << "a gain the nominal law does not have";
  // The prior's level with the fit's growth, and its sd (the gain's regression variance over G).
  EXPECT_NEAR(id.prior_level_film_ohm_m2(), kFilmOhmM2 + gain * g, 1e-15);
  EXPECT_GE(id.prior_level_film_sd_ohm_m2(), 1e-3);
  // The report: the inverse-variance mean of that prior and the fit.
  const double sp = id.prior_level_film_sd_ohm_m2(), sf = level.fitted_sd_ohm_m2();
  const double wp = 1.0 / (sp * sp), wf = 1.0 / (sf * sf);
  EXPECT_NEAR(level.r_film_ohm_m2(), (wp * id.prior_level_film_ohm_m2() + wf * id.film_ohm_m2()) / (wp + wf),
              1e-12 * kFilmOhmM2);
  EXPECT_NEAR(level.film_sd_ohm_m2(), 1.0 / std::sqrt(wp + wf), 1e-12 * sp);
  // Over more growth and no learning, the level-only report moves by the fit's gain times the
  // growth; the whole film's by a mean of that and the nominal law's.
  const double before_level = level.r_film_ohm_m2(), before_whole = whole.r_film_ohm_m2();
  level.propagate(-1.0, 1000.0);
  whole.propagate(-1.0, 1000.0);
  const double dg = level.identifier().growth_ohm_m2() - g;
  ASSERT_GT(dg, 0.0);
  EXPECT_NEAR((level.r_film_ohm_m2() - before_level) / dg, gain, 0.02 * std::fabs(gain));
  const double whole_rate = (whole.r_film_ohm_m2() - before_whole) / dg;
  EXPECT_GT(std::fabs(whole_rate - gain), 0.1 * std::fabs(gain - 1.0)) << "the whole film leans to the nominal law";
  std::printf("gain %.3f: reported growth per G %.3f (level alone), %.3f (whole film)\n", gain,
              (level.r_film_ohm_m2() - before_level) / dg, whole_rate);
}

}  // namespace

namespace {

// With the initial film's stated tolerance (Config::stated_film_initial_sd_rel) the prior's sd
// in the combination is that tolerance, not the regression's weak prior: the fit is the same
// bit for bit, the reported film leans further to the prior and its sd is sharper. Both the whole
// film's prior and the level-alone prior take it, and so does the prior held before a fit.
TEST(StatedSpread, TheInitialFilmsStatedToleranceIsThePriorsSd) {
  for (const bool level_only : {false, true}) {
    Path::Config weak = path_config(true), stated = path_config(true);
    weak.fuse_level_only = stated.fuse_level_only = level_only;
    stated.identifier.stated_film_initial_sd_rel = 0.1155;
    Path a(weak, kDtS), b(stated, kDtS);
    const SpreadModel model{2.0 * kFilmOhmM2 * kH};
    const double truth = 1.1 * kFilmOhmM2;
    fw::test::learn_ticks(a, model, 200, truth);
    fw::test::learn_ticks(b, model, 200, truth);
    ASSERT_FALSE(b.holding());
    EXPECT_EQ(a.identifier().film_ohm_m2(), b.identifier().film_ohm_m2()) << "the fit is the data's";
    EXPECT_EQ(a.fitted_sd_ohm_m2(), b.fitted_sd_ohm_m2());
    const fw::FilmGrowthIdentifier<double>& id = b.identifier();
    const double g = id.growth_ohm_m2(), r0_sd = 0.1155 * kFilmOhmM2;
    const double m = id.prior_film_ohm_m2() * stated.identifier.film_model_sd_rel;
    // The whole film's prior: the stated initial film, the nominal gain's prior over G, the model bound.
    EXPECT_NEAR(id.prior_film_sd_ohm_m2(), std::sqrt(r0_sd * r0_sd + g * g + m * m), 1e-12 * kFilmOhmM2);
    EXPECT_LT(id.prior_film_sd_ohm_m2(), a.identifier().prior_film_sd_ohm_m2());
    EXPECT_LT(id.prior_level_film_sd_ohm_m2(), a.identifier().prior_level_film_sd_ohm_m2());
    // The report is nearer the prior and sharper; still the inverse-variance mean.
    const double prior = level_only ? id.prior_level_film_ohm_m2() : id.prior_film_ohm_m2();
    const double sp = level_only ? id.prior_level_film_sd_ohm_m2() : id.prior_film_sd_ohm_m2();
    const double sf = b.fitted_sd_ohm_m2(), wp = 1.0 / (sp * sp), wf = 1.0 / (sf * sf);
    EXPECT_NEAR(b.r_film_ohm_m2(), (wp * prior + wf * id.film_ohm_m2()) / (wp + wf), 1e-12 * kFilmOhmM2);
    EXPECT_NEAR(b.film_sd_ohm_m2(), 1.0 / std::sqrt(wp + wf), 1e-12 * sp);
    EXPECT_LT(std::fabs(b.r_film_ohm_m2() - prior), std::fabs(a.r_film_ohm_m2() - prior)) << level_only;
    EXPECT_LT(b.film_sd_ohm_m2(), 0.6 * a.film_sd_ohm_m2()) << level_only;
  }
  // Without a stated spread nothing is combined: the tolerance is the held prior's sd before a fit
  // settles (the stated initial film, the nominal gain's prior over G, the model bound) and changes
  // nothing reported after.
  Path::Config plain = path_config(false), told = path_config(false);
  told.identifier.stated_film_initial_sd_rel = 0.1155;
  Path p(plain, kDtS), q(told, kDtS);
  ASSERT_TRUE(q.holding());
  EXPECT_EQ(p.r_film_ohm_m2(), q.r_film_ohm_m2());
  const double m0 = kFilmOhmM2 * told.identifier.film_model_sd_rel, r0_sd = 0.1155 * kFilmOhmM2;
  EXPECT_NEAR(q.film_sd_ohm_m2(), std::sqrt(r0_sd * r0_sd + m0 * m0), 1e-12 * kFilmOhmM2);
  EXPECT_NEAR(p.film_sd_ohm_m2(), std::sqrt(1e-6 + m0 * m0), 1e-12 * kFilmOhmM2) << "the weak prior, 1e-3 ohm m2";
  const SpreadModel model{0.0};
  fw::test::learn_ticks(p, model, 200, 1.1 * kFilmOhmM2);
  fw::test::learn_ticks(q, model, 200, 1.1 * kFilmOhmM2);
  ASSERT_FALSE(q.holding());
  EXPECT_EQ(p.r_film_ohm_m2(), q.r_film_ohm_m2());
  EXPECT_EQ(p.film_sd_ohm_m2(), q.film_sd_ohm_m2());
}

}  // namespace
