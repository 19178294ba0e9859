// The design-time bias's state-of-charge table (estimation/design_bias.hpp) of a cell other than
// the paper's, from its nominal DFN: finite, over the charges' stoichiometry range, and with it the
// nominal run's CC-charge residual spreads much less than with the constant alone (the shape the
// identification would otherwise put into the film). The table builder's binning on known data.
#include <gtest/gtest.h>

#include <cmath>
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
  EXPECT_GT(b.table.x_first, 0.0);
  EXPECT_LT(b.table.x_last, 1.0);
  const double spread_constant = b.residual_constant_v[2] - b.residual_constant_v[0];
  const double spread_table = b.residual_table_v[2] - b.residual_table_v[0];
  std::printf("lco nominal CC-charge residual 10/50/90 %%, mV: constant %.3f / %.3f / %.3f, table %.3f / %.3f / %.3f\n",
              1e3 * b.residual_constant_v[0], 1e3 * b.residual_constant_v[1], 1e3 * b.residual_constant_v[2],
              1e3 * b.residual_table_v[0], 1e3 * b.residual_table_v[1], 1e3 * b.residual_table_v[2]);
  EXPECT_GT(spread_constant, 1e-3) << "the LCO template's model error varies over a charge by mV";
  EXPECT_LT(spread_table, 0.5 * spread_constant) << "the table removes most of that";
  EXPECT_LT(std::fabs(b.residual_table_v[1]), 0.5e-3);
}

}  // namespace
}  // namespace bms
