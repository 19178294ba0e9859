#pragma once
// A function of one variable (stoichiometry, concentration, ...) with its exact derivative.
// The truth model's Jacobian is built by forward-mode differentiation, so every functional
// parameter must provide d/dx exactly, not by finite differences.
#include <memory>
#include <utility>

namespace bms {

class ScalarFunction {
 public:
  virtual ~ScalarFunction() = default;
  virtual double value(double x) const = 0;
  virtual double derivative(double x) const = 0;
  // Both at once: interpreted functions override this to evaluate once.
  virtual void value_and_derivative(double x, double& v, double& d) const {
    v = value(x);
    d = derivative(x);
  }
};

using ScalarFunctionPtr = std::shared_ptr<const ScalarFunction>;

class ConstantFunction final : public ScalarFunction {
 public:
  explicit ConstantFunction(double v) : v_(v) {}
  double value(double) const override { return v_; }
  double derivative(double) const override { return 0.0; }

 private:
  double v_;
};

// f times a constant factor, derivative included: a property scaled for one run (the truth's
// `--set conductivity_scale`, ...) without touching the function it came from.
class ScaledFunction final : public ScalarFunction {
 public:
  ScaledFunction(ScalarFunctionPtr f, double factor) : f_(std::move(f)), factor_(factor) {}
  double value(double x) const override { return factor_ * f_->value(x); }
  double derivative(double x) const override { return factor_ * f_->derivative(x); }
  void value_and_derivative(double x, double& v, double& d) const override {
    f_->value_and_derivative(x, v, d);
    v *= factor_;
    d *= factor_;
  }

 private:
  ScalarFunctionPtr f_;
  double factor_;
};

}  // namespace bms
