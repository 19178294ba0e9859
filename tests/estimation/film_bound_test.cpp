#include <gtest/gtest.h>

#include <cmath>
#include <vector>

#include "estimation/estimate_run.hpp"
#include "estimation/film_bound.hpp"
#include "sim/cell_catalog.hpp"

namespace {

using bms::EstimateRow;
using bms::fw::Mode;

constexpr double kH = 40.0;      // dV/dR_film [V per ohm m2]
constexpr double kS = 0.004;     // |dV/dnu| [V], alternating in sign within a charge
constexpr double kFilm = 3.7e-3;  // true film in the first scored charge [ohm m2]

// One CC charge of `ticks` rows at nominal-law integral G, true film `film`, learning or not,
// then one rest row that ends it.
void add_charge(std::vector<EstimateRow>& rows, int cycle, int ticks, double g_ohm_m2, double film, bool learning) {
  for (int k = 0; k <= ticks; ++k) {
    EstimateRow r{};
    r.t_s = static_cast<double>(rows.size());
    r.cycle = cycle;
    r.mode = k < ticks ? Mode::cc_charge : Mode::rest;
    r.rcsi_active = learning && k < ticks;
    r.r_film_true_ohm_m2 = r.r_film_est_ohm_m2 = film;
    r.markov_v_per_ohm_m2 = kH;
    r.inventory_sensitivity_v = (k % 2 == 0) ? kS : -kS;
    r.growth_ohm_m2 = g_ohm_m2;
    rows.push_back(r);
  }
}

// A charge without learning, then two learned ones of n ticks at G = 0 and G = g2 whose true
// film grows by d. With S orthogonal to the constants the inventory drops out, and the growth
// g g2 is a difference of two means: its bound is sigma sqrt(1/n + 1/n) / H, relative to d.
TEST(FilmBound, GrowthBoundIsTheDifferenceOfTwoChargesMeans) {
  std::vector<EstimateRow> rows;
  const int n = 1000;
  const double g2 = 2e-5, d = 3e-5, sigma_v = 2e-4;
  add_charge(rows, 1, 50, 0.0, kFilm - d, false);
  add_charge(rows, 2, n, 0.0, kFilm, true);
  add_charge(rows, 3, n, g2, kFilm + d, true);

  const bms::GrowthSpan span = bms::growth_span(rows);
  ASSERT_TRUE(span.valid);
  EXPECT_EQ(rows[span.ref].cycle, 2) << "the reference is the first charge that learned";
  EXPECT_EQ(rows[span.last].cycle, 3);

  const bms::FilmBound b = bms::film_cramer_rao(rows, sigma_v);
  ASSERT_TRUE(b.valid);
  const double expected_sd = sigma_v * std::sqrt(2.0 / n) / kH;
  EXPECT_NEAR(b.growth_sd_ohm_m2, expected_sd, 1e-9 * expected_sd);
  EXPECT_NEAR(b.growth_sd_pct, expected_sd / d * 100.0, 1e-7);
  // Twice the noise, twice the bound.
  EXPECT_NEAR(bms::film_cramer_rao(rows, 2.0 * sigma_v).growth_sd_ohm_m2, 2.0 * expected_sd, 1e-9 * expected_sd);
}

TEST(FilmBound, NoGrowthBoundWithoutTwoChargeEnds) {
  std::vector<EstimateRow> rows;
  add_charge(rows, 1, 200, 0.0, kFilm, true);
  const bms::FilmBound b = bms::film_cramer_rao(rows, 2e-4);
  EXPECT_FALSE(bms::growth_span(rows).valid);
  EXPECT_TRUE(std::isnan(b.growth_sd_ohm_m2));
  EXPECT_TRUE(std::isnan(b.growth_sd_pct));
}

TEST(FilmBound, GrowthBoundWithoutATrueGrowthIsNoPercentage) {
  std::vector<EstimateRow> rows;
  add_charge(rows, 1, 200, 0.0, kFilm, true);
  add_charge(rows, 2, 200, 1e-5, kFilm, true);  // the truth did not grow: no relative bound
  const bms::FilmBound b = bms::film_cramer_rao(rows, 2e-4);
  EXPECT_TRUE(std::isfinite(b.growth_sd_ohm_m2));
  EXPECT_TRUE(std::isnan(b.growth_sd_pct));
}

}  // namespace

// The current noise is folded in with each cell's own reduced model: the LCO's dV/dI at the start
// of its 1C charge, not the paper cell's. Without current noise the voltage noise is returned.
TEST(FilmBound, EffectiveNoiseUsesTheCellsOwnResistance) {
  const bms::CellParameters paper = bms::load_cell("paper"), lco = bms::load_cell("lco");
  const double sv = 0.2e-3, si = 5e-3;
  EXPECT_DOUBLE_EQ(bms::effective_voltage_noise_v(sv, 0.0, 0.873, lco), sv);
  const double r_paper = bms::effective_voltage_noise_v(0.0, si, 2.3, paper) / si;
  const double r_lco = bms::effective_voltage_noise_v(0.0, si, 0.873, lco) / si;
  EXPECT_GT(r_lco, 0.0);
  EXPECT_TRUE(std::isfinite(r_lco));
  // An 18650-class LCO cell is tens of milliohms; the paper cell's resistance is not it.
  EXPECT_LT(r_lco, 1.0);
  EXPECT_GT(std::abs(r_lco - r_paper) / r_paper, 0.05);
  const double both = bms::effective_voltage_noise_v(sv, si, 0.873, lco);
  EXPECT_NEAR(both, std::hypot(sv, r_lco * si), 1e-12);
}
