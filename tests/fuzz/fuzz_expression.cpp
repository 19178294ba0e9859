// Fuzz target: the BPX expression parser and evaluator (host_sim/src/io/expression.*).
// Input: the expression text. Bad text must end in InputError; anything else that escapes
// (another exception, a crash, UB) is a finding. Parsed programs are evaluated at points
// that provoke overflow, NaN and poles: evaluation runs on a fixed stack and must stay in it.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <limits>
#include <string_view>

#include "io/expression.hpp"
#include "io/input_error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  std::shared_ptr<const bms::ExpressionFunction> f;
  try {
    f = bms::ExpressionFunction::parse(text, "fuzz");
  } catch (const bms::InputError&) {
    return 0;
  }
  if (f->text() != text) std::abort();
  constexpr double kInf = std::numeric_limits<double>::infinity();
  for (const double x : {0.0, 0.5, 1.0, -1.0, 1e-300, 1e300, -1e300, kInf, -kInf,
                         std::numeric_limits<double>::quiet_NaN()}) {
    const auto r = f->evaluate(x);
    double v = 0.0, d = 0.0;
    f->value_and_derivative(x, v, d);
    // Evaluation is deterministic: both paths give bit-identical results (NaN aside).
    if ((v == v || r.value == r.value) && !(v == r.value)) std::abort();
  }
  return 0;
}
