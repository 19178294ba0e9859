#include "io/expression.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "io/input_error.hpp"

namespace bms {
namespace {

// The functional parameters of the About:Energy LFP BPX file (shared/data/aboutenergy-lfp18650).
constexpr const char* kNegativeOcp =
    "5.29210878e+01 * exp(-1.72699386e+02 * x) - 1.17963399e+03 + 1.20956356e+03 * "
    "tanh(6.72033948e+01 * (x + 2.44746396e-02)) + 4.52430314e-02 * tanh(-1.47542326e+01 * "
    "(x - 1.62746053e-01)) + 2.01855800e+01 * tanh(-2.46666302e+01 * (x - 1.12986136e+00)) + "
    "2.01708039e-02 * tanh(-1.19900231e+01 * (x - 5.49773440e-01)) + 4.99616805e+01 * "
    "tanh(-6.11370883e+01 * (x + 4.69382558e-03))";
constexpr const char* kPositiveOcp =
    "3.41285712e+00 - 1.49721852e-02 * x + 3.54866018e+14 * exp(-3.95729493e+02 * x) - "
    "1.45998465e+00 * exp(-1.10108622e+02 * (1 - x))";
constexpr const char* kNegativeEntropic =
    "(-0.1112 * x + 0.02914 + 0.3561 * exp(-((x - 0.08309) ** 2) / 0.004616)) / 1000";
constexpr const char* kElectrolyteConductivity =
    "0.1297 * (x / 1000) ** 3 - 2.51 * (x / 1000) ** 1.5 + 3.329 * (x / 1000)";

double eval(const std::string& text, double x = 0.0) {
  return ExpressionFunction::parse(text, "test")->value(x);
}
double slope(const std::string& text, double x) {
  return ExpressionFunction::parse(text, "test")->derivative(x);
}
std::string parse_error(const std::string& text) {
  try {
    ExpressionFunction::parse(text, "FILE: field 'OCP [V]'");
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(Expression, ArithmeticFollowsPythonPrecedence) {
  EXPECT_DOUBLE_EQ(eval("1 + 2 * 3"), 7.0);
  EXPECT_DOUBLE_EQ(eval("(1 + 2) * 3"), 9.0);
  EXPECT_DOUBLE_EQ(eval("2 ** 3 ** 2"), 512.0);  // right-associative
  EXPECT_DOUBLE_EQ(eval("-x ** 2", 3.0), -9.0);  // -(x**2)
  EXPECT_DOUBLE_EQ(eval("(-x) ** 2", 3.0), 9.0);
  EXPECT_DOUBLE_EQ(eval("-2 ** 2"), -4.0);
  EXPECT_DOUBLE_EQ(eval("2 ** -1"), 0.5);
  EXPECT_DOUBLE_EQ(eval("2 * -x", 3.0), -6.0);
  EXPECT_DOUBLE_EQ(eval("x / 2 / 4", 8.0), 1.0);
  EXPECT_DOUBLE_EQ(eval("x - 1 - 1", 5.0), 3.0);
  EXPECT_DOUBLE_EQ(eval("- - +x", 5.0), 5.0);
  EXPECT_DOUBLE_EQ(eval("10 - 2 * 3 ** 2 / 6"), 7.0);
}

TEST(Expression, NumbersFunctionsAndConstants) {
  EXPECT_DOUBLE_EQ(eval("5.29210878e+01"), 52.9210878);
  EXPECT_DOUBLE_EQ(eval("1E-2"), 0.01);
  EXPECT_DOUBLE_EQ(eval(".5"), 0.5);
  EXPECT_DOUBLE_EQ(eval("5."), 5.0);
  EXPECT_DOUBLE_EQ(eval("3e2"), 300.0);
  EXPECT_DOUBLE_EQ(eval("pi"), M_PI);
  EXPECT_DOUBLE_EQ(eval("e"), std::exp(1.0));
  EXPECT_DOUBLE_EQ(eval("exp(x)", 1.5), std::exp(1.5));
  EXPECT_DOUBLE_EQ(eval("log(x)", 1.5), std::log(1.5));
  EXPECT_DOUBLE_EQ(eval("log10(x)", 1000.0), 3.0);
  EXPECT_DOUBLE_EQ(eval("sqrt(x)", 2.25), 1.5);
  EXPECT_DOUBLE_EQ(eval("tanh(x)", 0.3), std::tanh(0.3));
  EXPECT_DOUBLE_EQ(eval("sinh(x)", 0.3), std::sinh(0.3));
  EXPECT_DOUBLE_EQ(eval("cosh(x)", 0.3), std::cosh(0.3));
  EXPECT_DOUBLE_EQ(eval("abs(-x)", 0.3), 0.3);
  EXPECT_DOUBLE_EQ(eval(" \t exp ( x )\n", 0.0), 1.0);
  EXPECT_NEAR(eval(kElectrolyteConductivity, 1000.0), 0.1297 - 2.51 + 3.329, 1e-12);
}

TEST(Expression, ExactDerivatives) {
  EXPECT_DOUBLE_EQ(slope("x ** 3", 2.0), 12.0);
  EXPECT_DOUBLE_EQ(slope("x ** 2", -3.0), -6.0);  // constant exponent: no log of a negative base
  EXPECT_DOUBLE_EQ(slope("x ** 2", 0.0), 0.0);
  EXPECT_DOUBLE_EQ(slope("2 ** x", 3.0), 8.0 * std::log(2.0));
  EXPECT_DOUBLE_EQ(slope("x ** x", 2.0), 4.0 * (std::log(2.0) + 1.0));
  EXPECT_DOUBLE_EQ(slope("exp(2 * x)", 0.5), 2.0 * std::exp(1.0));
  EXPECT_DOUBLE_EQ(slope("log(x)", 4.0), 0.25);
  EXPECT_DOUBLE_EQ(slope("log10(x)", 2.0), 1.0 / (2.0 * std::log(10.0)));
  EXPECT_DOUBLE_EQ(slope("sqrt(x)", 4.0), 0.25);
  EXPECT_DOUBLE_EQ(slope("tanh(x)", 0.5), 1.0 - std::tanh(0.5) * std::tanh(0.5));
  EXPECT_DOUBLE_EQ(slope("sinh(x)", 0.5), std::cosh(0.5));
  EXPECT_DOUBLE_EQ(slope("cosh(x)", 0.5), std::sinh(0.5));
  EXPECT_DOUBLE_EQ(slope("abs(x)", -0.5), -1.0);
  EXPECT_DOUBLE_EQ(slope("1 / x", 2.0), -0.25);
  EXPECT_DOUBLE_EQ(slope("x / (1 + x)", 1.0), 0.25);
  EXPECT_DOUBLE_EQ(slope("-x ** 2", 3.0), -6.0);
  EXPECT_DOUBLE_EQ(slope("7", 3.0), 0.0);
}

TEST(Expression, DerivativesMatchFiniteDifferencesOnBpxFunctions) {
  struct Case {
    const char* text;
    double lo, hi;
  };
  for (const Case& c :
       {Case{kNegativeOcp, 0.002, 0.99}, Case{kPositiveOcp, 0.01, 0.99},
        Case{kNegativeEntropic, 0.0, 1.0}, Case{kElectrolyteConductivity, 100.0, 3000.0}}) {
    const auto f = ExpressionFunction::parse(c.text, "test");
    for (int k = 0; k <= 40; ++k) {
      const double x = c.lo + (c.hi - c.lo) * k / 40.0;
      const double h = 1e-6 * std::max(1.0, std::fabs(x));
      const double fd = (f->value(x + h) - f->value(x - h)) / (2.0 * h);
      const auto [v, d] = f->evaluate(x);
      EXPECT_EQ(v, f->value(x));
      EXPECT_NEAR(d, fd, 1e-5 * std::max(1.0, std::fabs(d))) << c.text << " at x = " << x;
    }
  }
}

TEST(Expression, BpxOcpValuesArePlausible) {
  const auto negative = ExpressionFunction::parse(kNegativeOcp, "test");
  const auto positive = ExpressionFunction::parse(kPositiveOcp, "test");
  EXPECT_GT(negative->value(0.5), 0.05);
  EXPECT_LT(negative->value(0.5), 0.3);
  EXPECT_GT(positive->value(0.5), 3.2);
  EXPECT_LT(positive->value(0.5), 3.5);
  EXPECT_LT(negative->derivative(0.01), 0.0);  // OCP falls as the graphite fills
}

TEST(Expression, ErrorsNameTheFieldAndColumn) {
  EXPECT_EQ(parse_error("exp(x) + )"), "FILE: field 'OCP [V]': unexpected ')' at column 10");
  EXPECT_EQ(parse_error(""), "FILE: field 'OCP [V]': empty expression at column 1");
  EXPECT_EQ(parse_error("   "), "FILE: field 'OCP [V]': empty expression at column 4");
  EXPECT_EQ(parse_error("x +"), "FILE: field 'OCP [V]': unexpected end of expression at column 4");
  EXPECT_EQ(parse_error("((("), "FILE: field 'OCP [V]': unexpected end of expression at column 4");
  EXPECT_EQ(parse_error("(x + 1))"), "FILE: field 'OCP [V]': unexpected ')' at column 8");
  EXPECT_EQ(parse_error("(x + 1"), "FILE: field 'OCP [V]': missing ')' at column 7");
  EXPECT_EQ(parse_error("exp(x, 2)"),
            "FILE: field 'OCP [V]': expected ')' but found ',' at column 6");
  EXPECT_NE(parse_error("1 + foo(x)").find("unknown function 'foo' (the variable is 'x'"),
            std::string::npos);
  EXPECT_NE(parse_error("1 + foo(x)").find("at column 5"), std::string::npos);
  EXPECT_NE(parse_error("2 * y").find("unknown name 'y'"), std::string::npos);
  EXPECT_NE(parse_error("exp").find("expected '(' after function 'exp' at column 4"),
            std::string::npos);
  EXPECT_NE(parse_error("x y").find("unexpected 'y' at column 3"), std::string::npos);
  EXPECT_NE(parse_error("2x").find("invalid number at column 1"), std::string::npos);
  EXPECT_NE(parse_error("1.2.3").find("invalid number"), std::string::npos);
  EXPECT_NE(parse_error("1_000").find("invalid number"), std::string::npos);
  EXPECT_NE(parse_error("3e").find("invalid number"), std::string::npos);
  EXPECT_NE(parse_error("1e999").find("number out of range"), std::string::npos);
  EXPECT_NE(parse_error("x // 2").find("unsupported operator '//' at column 3"), std::string::npos);
  EXPECT_NE(parse_error("x % 2").find("unexpected '%'"), std::string::npos);
  EXPECT_NE(parse_error("x ** * 2").find("unexpected '*' at column 6"), std::string::npos);
  EXPECT_NE(parse_error("x(2)").find("unexpected '(' at column 2"), std::string::npos);
  EXPECT_NE(parse_error("__import__('os').system('ls')").find("unknown function '__import__'"),
            std::string::npos);
  EXPECT_NE(parse_error("x\x01").find("unexpected byte 0x01 at column 2"), std::string::npos);
}

TEST(Expression, HostileNestingIsRejectedNotRecursed) {
  const std::string deep_parens = std::string(10000, '(') + "x" + std::string(10000, ')');
  EXPECT_NE(parse_error(deep_parens).find("longer than 4096 characters"), std::string::npos);

  EXPECT_NE(
      parse_error(std::string(100, '(') + "x" + std::string(100, ')')).find("nested too deeply"),
      std::string::npos);
  EXPECT_NE(parse_error(std::string(2000, '-') + "x").find("nested too deeply"), std::string::npos);
  std::string tower = "x";
  for (int i = 0; i < 500; ++i) tower += "**x";
  EXPECT_NE(parse_error(tower).find("nested too deeply"), std::string::npos);

  // Within the limits it works, and long flat sums are fine.
  EXPECT_DOUBLE_EQ(eval(std::string(60, '(') + "x" + std::string(60, ')'), 2.0), 2.0);
  std::string sum = "x";
  for (int i = 0; i < 1000; ++i) sum += "+x";
  EXPECT_DOUBLE_EQ(eval(sum, 1.0), 1001.0);
  EXPECT_DOUBLE_EQ(slope(sum, 1.0), 1001.0);
}

TEST(Expression, RandomInputNeverCrashes) {
  const std::string alphabet = "x0123456789.eE+-*/() \texplogsqrtanhcb,_#";
  std::mt19937 rng(12345);
  std::uniform_int_distribution<std::size_t> length(0, 40);
  std::uniform_int_distribution<std::size_t> pick(0, alphabet.size() - 1);
  int parsed = 0;
  for (int i = 0; i < 20000; ++i) {
    std::string text(length(rng), ' ');
    for (char& ch : text) ch = alphabet[pick(rng)];
    try {
      const auto f = ExpressionFunction::parse(text, "fuzz");
      (void)f->evaluate(0.3);
      ++parsed;
    } catch (const InputError&) {
    }
  }
  EXPECT_GT(parsed, 0);
}

}  // namespace
}  // namespace bms
