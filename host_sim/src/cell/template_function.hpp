#pragma once
// Adapts a function template f<T>(T) into a ScalarFunction whose derivative is exact
// (evaluated with a dual number), so built-in parameter sets need no hand-written derivatives.
#include "bms/fw/model/dual.hpp"
#include "cell/scalar_function.hpp"

namespace bms {

template <typename F>
class TemplateFunction final : public ScalarFunction {
 public:
  explicit TemplateFunction(F f) : f_(f) {}
  double value(double x) const override { return f_(x); }
  double derivative(double x) const override { return f_(fw::Dual<double>{x, 1.0}).d; }

 private:
  F f_;
};

template <typename F>
ScalarFunctionPtr make_template_function(F f) {
  return std::make_shared<TemplateFunction<F>>(f);
}

}  // namespace bms
