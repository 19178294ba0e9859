#pragma once
// BPX functional parameters written as Python-style expressions in one variable `x`,
// e.g. "3.4 - 1.5e-2 * x + 3.5e14 * exp(-395.7 * x)". The text is parsed once into a
// postfix program; evaluation runs that program in forward mode, so the derivative is
// exact (the truth model's Jacobian needs it) and no text is ever executed.
#include <memory>
#include <string>
#include <string_view>
#include <vector>

#include "cell/scalar_function.hpp"

namespace bms {

class ExpressionFunction final : public ScalarFunction {
 public:
  // Hostile input is bounded: longer texts or deeper nesting are rejected, not recursed into.
  static constexpr std::size_t kMaxLength = 4096;
  static constexpr int kMaxDepth = 64;

  // Throws InputError "<where>: <problem> at column N" (1-based column in `text`).
  static std::shared_ptr<const ExpressionFunction> parse(std::string_view text,
                                                         std::string_view where);

  struct ValueAndDerivative {
    double value;
    double derivative;
  };
  ValueAndDerivative evaluate(double x) const;
  double value(double x) const override { return evaluate(x).value; }
  double derivative(double x) const override { return evaluate(x).derivative; }
  void value_and_derivative(double x, double& v, double& d) const override {
    const auto r = evaluate(x);
    v = r.value;
    d = r.derivative;
  }

  const std::string& text() const { return text_; }

 private:
  class Parser;
  enum class Op : unsigned char {
    constant,
    variable,
    negate,
    add,
    subtract,
    multiply,
    divide,
    power,
    exp,
    log,
    log10,
    sqrt,
    tanh,
    sinh,
    cosh,
    abs
  };
  struct Instruction {
    Op op;
    double constant;  // used by Op::constant only
  };
  static bool apply_unary(Op op, ValueAndDerivative& u);
  static void apply_binary(Op op, ValueAndDerivative& a, const ValueAndDerivative& b);
  // The parser rejects programs needing more (far beyond kMaxDepth's reach), so evaluation
  // runs on a fixed array: no heap, no overflow.
  static constexpr std::size_t kMaxStack = 256;

  ExpressionFunction(std::string text, std::vector<Instruction> program)
      : text_(std::move(text)), program_(std::move(program)) {}

  std::string text_;
  std::vector<Instruction> program_;
};

}  // namespace bms
