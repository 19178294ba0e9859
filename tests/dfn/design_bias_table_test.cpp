// The design-time bias's state-of-charge table (estimation/design_bias.hpp) of a cell other than
// the paper's, from its nominal DFN: finite, over the charges' stoichiometry range, and with it the
// nominal run's CC-charge residual spreads much less than with the constant alone (the shape the
// identification would otherwise put into the film). The table builder's binning on known data.
#include <gtest/gtest.h>

#include <array>
#include <cmath>
#include <cstdio>
#include <algorithm>
#include <string>
#include <vector>

#include "estimation/design_bias.hpp"
#include "io/input_error.hpp"
#include "sim/cell_catalog.hpp"

namespace bms {
namespace {

TEST(DesignBiasTable, BinsMediansAndFillsEmptyKnots) {
  constexpr int kN = fw::ModelBiasTable<double>::kKnots;
  std::vector<double> x, ratio;
  for (int i = 0; i <= 2300; ++i) {  // 0.1 .. 0.33, a line in x, one outlier per knot
    const double xi = 0.1 + 1e-4 * i;
    if (xi > 0.18 && xi < 0.22) continue;  // a gap: knots without ticks
    x.push_back(xi);
    ratio.push_back(i % 100 == 7 ? 1.0 : 2e-3 * xi);
  }
  const fw::ModelBiasTable<double> t = bias_table_of(x, ratio);
  ASSERT_TRUE(t.on());
  EXPECT_DOUBLE_EQ(t.x_first, 0.1);
  EXPECT_NEAR(t.x_last, 0.33, 1e-12);
  ASSERT_TRUE(t.valid());
  for (int k = 0; k < kN; ++k) {
    const double xk = t.x_first + k * (t.x_last - t.x_first) / (kN - 1);
    EXPECT_NEAR(t.ohm[k], 2e-3 * xk, 6e-6) << "knot " << k << " (a median: the outliers do not move it; the end and gap-edge bins are half bins)";
  }
  EXPECT_THROW(bias_table_of({}, {}), RuntimeFailure);
}

TEST(DesignBiasTable, LcoTableIsFiniteAndNarrowsTheNominalResidual) {
  const DesignBias b = design_time_bias(load_cell("lco"));
  ASSERT_TRUE(std::isfinite(b.bias_ohm));
  ASSERT_TRUE(b.table.on());
  ASSERT_TRUE(b.table.valid());
  EXPECT_GT(b.table.nominal().x_first, 0.0);
  EXPECT_LT(b.table.nominal().x_last, 1.0);
  const double spread_constant = b.residual_constant_v[2] - b.residual_constant_v[0];
  const double spread_table = b.residual_table_v[2] - b.residual_table_v[0];
  std::printf("lco nominal CC-charge residual 10/50/90 %%, mV: constant %.3f / %.3f / %.3f, table %.3f / %.3f / %.3f\n",
              1e3 * b.residual_constant_v[0], 1e3 * b.residual_constant_v[1], 1e3 * b.residual_constant_v[2],
              1e3 * b.residual_table_v[0], 1e3 * b.residual_table_v[1], 1e3 * b.residual_table_v[2]);
  EXPECT_GT(spread_constant, 1e-3) << "the LCO template's model error varies over a charge by mV";
  EXPECT_LT(spread_table, 0.5 * spread_constant) << "the table removes most of that";
  EXPECT_LT(std::fabs(b.residual_table_v[1]), 0.5e-3);
}

// The trusted span ends below the highest run of knots whose misfit exceeds the tolerance; a last
// knot that fits leaves no end.
TEST(DesignBiasTable, TrustedSpanEndsBelowTheKnotsThatMisfit) {
  constexpr int kN = fw::kModelBiasKnots;
  fw::ModelBiasTable<double> t;
  t.x_first = 0.2;
  t.x_last = 0.2 + 0.01 * (kN - 1);
  std::array<double, kN> misfit{};
  misfit.fill(0.1e-3);
  EXPECT_TRUE(std::isinf(trusted_span_end(t, misfit, 1.5e-3)));
  misfit[3] = 5e-3;  // a misfit low in the charge does not end the span
  misfit[kN - 1] = 26e-3;
  misfit[kN - 2] = 4.5e-3;
  EXPECT_NEAR(trusted_span_end(t, misfit, 1.5e-3), 0.2 + 0.01 * (kN - 3 + 0.5), 1e-12);
  EXPECT_TRUE(std::isinf(trusted_span_end(fw::ModelBiasTable<double>{}, misfit, 1.5e-3))) << "a table that is off";
  const std::vector<double> x = {0.2, 0.2, 0.2, 0.2 + 0.01 * (kN - 1)}, r = {1e-3, -2e-3, 0.0, 7e-3};
  const auto m = knot_misfit_v(t, x, r);
  EXPECT_DOUBLE_EQ(m[0], 2e-3) << "the 90th percentile of |r| (nearest rank) of the first knot's three ticks";
  EXPECT_DOUBLE_EQ(m[kN - 1], 7e-3);
  EXPECT_EQ(m[5], 0.0) << "a knot without ticks";
}

// The About:Energy LFP's nominal charge ends on a knee the table's medians miss: its span ends
// inside the table's range, at a knot whose misfit fits and below the last knot's; the LCO
// template fits to its last knot and has none.
TEST(DesignBiasTable, AboutEnergyKneeEndsTheTrustedSpanLcoHasNone) {
  const DesignBias ae_levels = design_time_bias(load_cell("aboutenergy"));
  ASSERT_TRUE(ae_levels.table.on());
  const fw::ModelBiasTable<double>& ae_table = ae_levels.table.nominal();
  struct {
    const fw::ModelBiasTable<double>& table;
    const std::array<double, fw::kModelBiasKnots>& knot_misfit_v;
  } ae{ae_table, ae_levels.knot_misfit_v};
  std::printf("aboutenergy trusted span end %.4f (table %.4f-%.4f), last knots' misfit %.2f / %.2f mV\n",
              ae.table.x_trusted_last, ae.table.x_first, ae.table.x_last, 1e3 * ae.knot_misfit_v[fw::kModelBiasKnots - 2],
              1e3 * ae.knot_misfit_v[fw::kModelBiasKnots - 1]);
  EXPECT_GT(ae.table.x_trusted_last, ae.table.x_first + 0.5 * (ae.table.x_last - ae.table.x_first));
  EXPECT_LT(ae.table.x_trusted_last, ae.table.x_last);
  EXPECT_GT(ae.knot_misfit_v[fw::kModelBiasKnots - 1], 10e-3) << "the knee: tens of mV";
  const DesignBias lco = design_time_bias(load_cell("lco"));
  EXPECT_TRUE(std::isinf(lco.table.nominal().x_trusted_last));
  // The levels over the inventory: each its own calibration (another table, another span), the
  // nominal level the single table's; the LCO's levels too, without a span.
  EXPECT_EQ(ae_levels.table.nu_step, 0.01);
  ASSERT_TRUE(ae_levels.table.valid());
  EXPECT_TRUE(ae_levels.level_notes.empty());
  for (int k : {0, 2}) {
    const auto& level = ae_levels.table.level[k];
    ASSERT_TRUE(level.on()) << "level " << k;
    double largest = 0.0;
    for (int i = 0; i < fw::kModelBiasKnots; ++i) largest = std::max(largest, std::fabs(level.ohm[i] - ae_table.ohm[i]));
    EXPECT_GT(largest, 1e-5) << "level " << k << " is its own calibration";
    EXPECT_TRUE(std::isfinite(level.x_trusted_last)) << "level " << k;
  }
  EXPECT_LT(ae_levels.table.level[0].x_trusted_last, ae_levels.table.level[2].x_trusted_last)
      << "the knee at another model stoichiometry with another inventory";
  EXPECT_TRUE(lco.table.level[0].on() && lco.table.level[2].on());
  EXPECT_TRUE(std::isinf(lco.table.level[2].x_trusted_last));
}

// A level whose nominal DFN cannot run the protocol (the NMC template's anode fills at the CV end
// with 1 % more lithium) stays the nominal one, and the calibration says so.
TEST(DesignBiasTable, ALevelTheCellCannotReachIsTheNominalOneAndSaid) {
  const DesignBias nmc = design_time_bias(load_cell("nmc"));
  ASSERT_EQ(nmc.level_notes.size(), 1u);
  EXPECT_NE(nmc.level_notes[0].find("rich"), std::string::npos) << nmc.level_notes[0];
  for (int i = 0; i < fw::kModelBiasKnots; ++i) EXPECT_EQ(nmc.table.level[2].ohm[i], nmc.table.nominal().ohm[i]);
  EXPECT_TRUE(nmc.table.level[0].on());
}

}  // namespace
}  // namespace bms
