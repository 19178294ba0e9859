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

// f(x) g(x), derivative included: a property's own function times a profile laid over it.
class ProductFunction final : public ScalarFunction {
 public:
  ProductFunction(ScalarFunctionPtr f, ScalarFunctionPtr g) : f_(std::move(f)), g_(std::move(g)) {}
  double value(double x) const override { return f_->value(x) * g_->value(x); }
  double derivative(double x) const override {
    double v = 0.0, d = 0.0;
    value_and_derivative(x, v, d);
    return d;
  }
  void value_and_derivative(double x, double& v, double& d) const override {
    double fv = 0.0, fd = 0.0, gv = 0.0, gd = 0.0;
    f_->value_and_derivative(x, fv, fd);
    g_->value_and_derivative(x, gv, gd);
    v = fv * gv;
    d = fd * gv + fv * gd;
  }

 private:
  ScalarFunctionPtr f_, g_;
};

// f(x) / f(x0): a function relative to its value at one point (a BPX expression for a
// diffusivity, D(x) / D(0.5), around the constant the rest of the host uses).
inline ScalarFunctionPtr relative_to(const ScalarFunctionPtr& f, double x0) {
  return std::make_shared<ScaledFunction>(f, 1.0 / f->value(x0));
}

}  // namespace bms
