#include "io/table_function.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <string>

#include "io/input_error.hpp"

namespace bms {
namespace {

std::string table_error(std::vector<double> x, std::vector<double> y) {
  try {
    TableFunction(std::move(x), std::move(y), "FILE: field 'Entropic change coefficient [V.K-1]'");
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(TableFunction, InterpolatesLinearlyAndHoldsEnds) {
  const TableFunction f({0.0, 1.0, 3.0}, {10.0, 12.0, 8.0}, "test");
  EXPECT_DOUBLE_EQ(f.value(0.0), 10.0);
  EXPECT_DOUBLE_EQ(f.value(0.25), 10.5);
  EXPECT_DOUBLE_EQ(f.value(1.0), 12.0);
  EXPECT_DOUBLE_EQ(f.value(2.0), 10.0);
  EXPECT_DOUBLE_EQ(f.value(3.0), 8.0);
  EXPECT_DOUBLE_EQ(f.value(-5.0), 10.0);
  EXPECT_DOUBLE_EQ(f.value(7.0), 8.0);

  EXPECT_DOUBLE_EQ(f.derivative(0.5), 2.0);
  EXPECT_DOUBLE_EQ(f.derivative(2.5), -2.0);
  EXPECT_DOUBLE_EQ(f.derivative(1.0), -2.0);  // a knot takes the segment to its right
  EXPECT_DOUBLE_EQ(f.derivative(0.0), 2.0);
  EXPECT_DOUBLE_EQ(f.derivative(3.0), -2.0);
  EXPECT_DOUBLE_EQ(f.derivative(-0.1), 0.0);
  EXPECT_DOUBLE_EQ(f.derivative(3.1), 0.0);

  const double nan = std::numeric_limits<double>::quiet_NaN();
  EXPECT_TRUE(std::isnan(f.value(nan)));
  EXPECT_TRUE(std::isnan(f.derivative(nan)));
}

TEST(TableFunction, TwoPointsAreEnough) {
  const TableFunction f({1.0, 2.0}, {0.0, -1.0}, "test");
  EXPECT_DOUBLE_EQ(f.value(1.5), -0.5);
  EXPECT_DOUBLE_EQ(f.derivative(1.5), -1.0);
}

TEST(TableFunction, RejectsBadTablesNamingTheField) {
  const std::string field = "FILE: field 'Entropic change coefficient [V.K-1]': ";
  EXPECT_EQ(table_error({0.0, 1.0}, {1.0}), field + "table has 2 x values but 1 y values");
  EXPECT_EQ(table_error({0.0}, {1.0}), field + "table needs at least 2 points, has 1");
  EXPECT_EQ(table_error({}, {}), field + "table needs at least 2 points, has 0");
  EXPECT_EQ(table_error({0.0, 1.0, 1.0}, {1.0, 2.0, 3.0}),
            field + "table x must strictly increase, but x[2] = 1 follows x[1] = 1");
  EXPECT_EQ(table_error({0.0, 2.0, 1.0}, {1.0, 2.0, 3.0}),
            field + "table x must strictly increase, but x[2] = 1 follows x[1] = 2");
  const double inf = std::numeric_limits<double>::infinity();
  EXPECT_EQ(table_error({0.0, 1.0}, {1.0, inf}),
            field + "table point 1 (x = 1, y = inf) is not finite");
  EXPECT_NE(table_error({std::nan(""), 1.0}, {1.0, 2.0}).find("table point 0"), std::string::npos);
}

}  // namespace
}  // namespace bms
