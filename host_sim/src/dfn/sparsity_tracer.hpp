#pragma once
// A scalar that carries, beside its value, the set of unknowns it depends on. One evaluation
// of the residual with it gives the Jacobian's structural pattern in time proportional to its
// nonzeros (a probe column by column with dual numbers costs n residual evaluations: 3.35 s
// at 80 volumes per region and 80 per particle). Structural means every dependence the code
// can take, whatever the values: the clamps of the model keep their argument's dependences.
#include <algorithm>
#include <cmath>
#include <iterator>
#include <utility>
#include <vector>

#include "bms/fw/model/dual.hpp"

namespace bms {

struct SparsityTracer {
  double v = 0.0;
  std::vector<int> deps;  // sorted, unique

  SparsityTracer() = default;
  SparsityTracer(double value) : v(value) {}  // NOLINT: implicit from constants, as fw::Dual
  SparsityTracer(double value, std::vector<int> d) : v(value), deps(std::move(d)) {}

  static SparsityTracer merge(double value, const SparsityTracer& a, const SparsityTracer& b) {
    if (a.deps.empty()) return {value, b.deps};
    if (b.deps.empty()) return {value, a.deps};
    std::vector<int> u;
    u.reserve(a.deps.size() + b.deps.size());
    std::set_union(a.deps.begin(), a.deps.end(), b.deps.begin(), b.deps.end(), std::back_inserter(u));
    return {value, std::move(u)};
  }
  SparsityTracer with_value(double value) const { return {value, deps}; }
};

inline SparsityTracer operator+(const SparsityTracer& a, const SparsityTracer& b) { return SparsityTracer::merge(a.v + b.v, a, b); }
inline SparsityTracer operator-(const SparsityTracer& a, const SparsityTracer& b) { return SparsityTracer::merge(a.v - b.v, a, b); }
inline SparsityTracer operator*(const SparsityTracer& a, const SparsityTracer& b) { return SparsityTracer::merge(a.v * b.v, a, b); }
inline SparsityTracer operator/(const SparsityTracer& a, const SparsityTracer& b) { return SparsityTracer::merge(a.v / b.v, a, b); }
inline SparsityTracer operator-(const SparsityTracer& a) { return a.with_value(-a.v); }
inline SparsityTracer operator+(const SparsityTracer& a, double b) { return a.with_value(a.v + b); }
inline SparsityTracer operator+(double b, const SparsityTracer& a) { return a.with_value(b + a.v); }
inline SparsityTracer operator-(const SparsityTracer& a, double b) { return a.with_value(a.v - b); }
inline SparsityTracer operator-(double b, const SparsityTracer& a) { return a.with_value(b - a.v); }
inline SparsityTracer operator*(const SparsityTracer& a, double b) { return a.with_value(a.v * b); }
inline SparsityTracer operator*(double b, const SparsityTracer& a) { return a.with_value(b * a.v); }
inline SparsityTracer operator/(const SparsityTracer& a, double b) { return a.with_value(a.v / b); }
inline SparsityTracer operator/(double b, const SparsityTracer& a) { return a.with_value(b / a.v); }
inline bool operator<(const SparsityTracer& a, const SparsityTracer& b) { return a.v < b.v; }
inline bool operator>(const SparsityTracer& a, const SparsityTracer& b) { return a.v > b.v; }

inline SparsityTracer exp(const SparsityTracer& a) { return a.with_value(std::exp(a.v)); }
inline SparsityTracer log(const SparsityTracer& a) { return a.with_value(std::log(a.v)); }
inline SparsityTracer sqrt(const SparsityTracer& a) { return a.with_value(std::sqrt(a.v)); }
inline SparsityTracer sinh(const SparsityTracer& a) { return a.with_value(std::sinh(a.v)); }
inline SparsityTracer tanh(const SparsityTracer& a) { return a.with_value(std::tanh(a.v)); }

}  // namespace bms

namespace bms::fw {
inline double value_of(const bms::SparsityTracer& x) { return x.v; }
}  // namespace bms::fw
