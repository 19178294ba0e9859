#pragma once
// Forward-mode dual number with K derivative directions at once (vector mode): one residual
// evaluation gives the Jacobian columns of K colours, so the values - the OCP fits, the
// exponentials of the kinetics, interpreted BPX expressions - are computed once instead of
// once per colour as with fw::Dual.
#include <array>
#include <cmath>

#include "bms/fw/model/dual.hpp"

namespace bms {

template <int K>
struct MultiDual {
  double v = 0.0;
  std::array<double, K> d{};

  MultiDual() = default;
  MultiDual(double value) : v(value) {}  // NOLINT: implicit from constants, as fw::Dual
  // Value and derivatives of f(x) from f(x.v) and f'(x.v).
  static MultiDual chain(const MultiDual& x, double value, double slope) {
    MultiDual r(value);
    for (int k = 0; k < K; ++k) r.d[k] = slope * x.d[k];
    return r;
  }

  MultiDual& operator+=(const MultiDual& o) {
    v += o.v;
    for (int k = 0; k < K; ++k) d[k] += o.d[k];
    return *this;
  }
  MultiDual& operator-=(const MultiDual& o) {
    v -= o.v;
    for (int k = 0; k < K; ++k) d[k] -= o.d[k];
    return *this;
  }
  MultiDual& operator*=(const MultiDual& o) {
    for (int k = 0; k < K; ++k) d[k] = d[k] * o.v + v * o.d[k];
    v *= o.v;
    return *this;
  }
  MultiDual& operator/=(const MultiDual& o) {
    const double inv = 1.0 / o.v;
    for (int k = 0; k < K; ++k) d[k] = (d[k] - v * inv * o.d[k]) * inv;
    v *= inv;
    return *this;
  }
  MultiDual& operator*=(double s) {
    v *= s;
    for (int k = 0; k < K; ++k) d[k] *= s;
    return *this;
  }
};

template <int K> MultiDual<K> operator+(MultiDual<K> a, const MultiDual<K>& b) { return a += b; }
template <int K> MultiDual<K> operator-(MultiDual<K> a, const MultiDual<K>& b) { return a -= b; }
template <int K> MultiDual<K> operator*(MultiDual<K> a, const MultiDual<K>& b) { return a *= b; }
template <int K> MultiDual<K> operator/(MultiDual<K> a, const MultiDual<K>& b) { return a /= b; }
template <int K> MultiDual<K> operator-(MultiDual<K> a) { return a *= -1.0; }
template <int K> MultiDual<K> operator+(MultiDual<K> a, double b) { a.v += b; return a; }
template <int K> MultiDual<K> operator+(double b, MultiDual<K> a) { a.v += b; return a; }
template <int K> MultiDual<K> operator-(MultiDual<K> a, double b) { a.v -= b; return a; }
template <int K> MultiDual<K> operator-(double b, MultiDual<K> a) { a *= -1.0; a.v += b; return a; }
template <int K> MultiDual<K> operator*(MultiDual<K> a, double b) { return a *= b; }
template <int K> MultiDual<K> operator*(double b, MultiDual<K> a) { return a *= b; }
template <int K> MultiDual<K> operator/(MultiDual<K> a, double b) {
  a.v /= b;
  for (int k = 0; k < K; ++k) a.d[k] /= b;
  return a;
}
template <int K> MultiDual<K> operator/(double b, const MultiDual<K>& a) {
  const double inv = 1.0 / a.v;
  return MultiDual<K>::chain(a, b * inv, -b * inv * inv);
}
template <int K> bool operator<(const MultiDual<K>& a, const MultiDual<K>& b) { return a.v < b.v; }
template <int K> bool operator>(const MultiDual<K>& a, const MultiDual<K>& b) { return a.v > b.v; }

template <int K> MultiDual<K> exp(const MultiDual<K>& a) {
  const double e = std::exp(a.v);
  return MultiDual<K>::chain(a, e, e);
}
// log and sqrt divide as fw::Dual does, so both give the same Jacobian to the last bit.
template <int K> MultiDual<K> log(const MultiDual<K>& a) {
  MultiDual<K> r(std::log(a.v));
  for (int k = 0; k < K; ++k) r.d[k] = a.d[k] / a.v;
  return r;
}
template <int K> MultiDual<K> sqrt(const MultiDual<K>& a) {
  const double s = std::sqrt(a.v);
  MultiDual<K> r(s);
  for (int k = 0; k < K; ++k) r.d[k] = a.d[k] / (2.0 * s);
  return r;
}
template <int K> MultiDual<K> sinh(const MultiDual<K>& a) {
  return MultiDual<K>::chain(a, std::sinh(a.v), std::cosh(a.v));
}
template <int K> MultiDual<K> tanh(const MultiDual<K>& a) {
  const double t = std::tanh(a.v);
  return MultiDual<K>::chain(a, t, 1.0 - t * t);
}

// The Jacobian's width: directions per residual evaluation (more colours take more passes).
inline constexpr int kJacobianLanes = 8;
using JacobianDual = MultiDual<kJacobianLanes>;

}  // namespace bms

namespace bms::fw {
// fw::value_of for the model code templated on its scalar.
template <int K> double value_of(const bms::MultiDual<K>& x) { return x.v; }
}  // namespace bms::fw
