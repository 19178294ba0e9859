#pragma once
// A solid diffusivity that depends on the local stoichiometry x = c_s / c_max: the factor on the
// electrode's constant D (ElectrodeParameters::solid_diffusivity_factor).
//
// The knee profile: constant below the knee stoichiometry x_k, then log-linear in x up to
// x = 1, where the factor is 10^s:
//     factor(x) = 10^(s * clamp((x - x_k) / (1 - x_k), 0, 1)).
// s < 0 makes diffusion slower towards full lithiation: the shape the About:Energy LFP records
// ask for (docs/results/diagnosis.md); LFP's apparent diffusivity from titration measurements is
// known to vary by orders of magnitude with x. The shape is this project's choice and its two
// numbers are fitted (`diagnose`), not taken from a source. x_k = 0: log-linear over all x.
// The same knee shape is the resistive reactant's rise over its resistance (dfn/dfn_model.hpp).
#include <algorithm>
#include <cmath>
#include <memory>

#include "cell/scalar_function.hpp"

namespace bms {

class KneeDiffusivityProfile final : public ScalarFunction {
 public:
  KneeDiffusivityProfile(double log10_at_full, double knee_stoich)
      : s_(log10_at_full), knee_(knee_stoich) {}
  double value(double x) const override {
    double v = 0.0, d = 0.0;
    value_and_derivative(x, v, d);
    return v;
  }
  double derivative(double x) const override {
    double v = 0.0, d = 0.0;
    value_and_derivative(x, v, d);
    return d;
  }
  void value_and_derivative(double x, double& v, double& d) const override {
    const double u = (x - knee_) / (1.0 - knee_);
    const bool inside = u > 0.0 && u < 1.0;
    v = std::pow(10.0, s_ * std::clamp(u, 0.0, 1.0));
    d = inside ? v * std::log(10.0) * s_ / (1.0 - knee_) : 0.0;
  }

 private:
  double s_, knee_;
};

// The factor of a cell's own D(x) (null = constant) with a knee profile laid over it (s = 0: none).
inline ScalarFunctionPtr with_knee_profile(const ScalarFunctionPtr& own, double log10_at_full, double knee_stoich) {
  if (log10_at_full == 0.0) return own;
  auto knee = std::make_shared<KneeDiffusivityProfile>(log10_at_full, knee_stoich);
  if (!own) return knee;
  return std::make_shared<ProductFunction>(own, std::move(knee));
}

}  // namespace bms
