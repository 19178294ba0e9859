#pragma once
// Forward-mode dual number: a value and one exact directional derivative.
// Used to differentiate the same templated model code that computes residuals, so the
// Jacobians (host DAE solver, firmware Newton step) are exact and cannot drift from the model.
// Header-only, no heap, usable on the target.
#include <cmath>
#include <type_traits>

namespace bms::fw {

template <typename S>
struct Dual {
  S v{};  // value
  S d{};  // derivative along the seeded direction

  constexpr Dual() = default;
  constexpr Dual(S value) : v(value), d(S(0)) {}  // NOLINT: implicit from constants is intended
  constexpr Dual(S value, S deriv) : v(value), d(deriv) {}
  // T(0.0911) in code templated on T must mean what float(0.0911) means: a deliberate
  // rounding of a literal, not a silent narrowing.
  template <typename U, typename = std::enable_if_t<std::is_arithmetic<U>::value && !std::is_same<U, S>::value>>
  constexpr explicit Dual(U value) : v(static_cast<S>(value)), d(S(0)) {}

  constexpr Dual& operator+=(const Dual& o) { v += o.v; d += o.d; return *this; }
  constexpr Dual& operator-=(const Dual& o) { v -= o.v; d -= o.d; return *this; }
  constexpr Dual& operator*=(const Dual& o) { d = d * o.v + v * o.d; v *= o.v; return *this; }
  constexpr Dual& operator/=(const Dual& o) {
    const S inv = S(1) / o.v;
    d = (d - v * inv * o.d) * inv;
    v *= inv;
    return *this;
  }
};

template <typename S> constexpr Dual<S> operator+(Dual<S> a, const Dual<S>& b) { return a += b; }
template <typename S> constexpr Dual<S> operator-(Dual<S> a, const Dual<S>& b) { return a -= b; }
template <typename S> constexpr Dual<S> operator*(Dual<S> a, const Dual<S>& b) { return a *= b; }
template <typename S> constexpr Dual<S> operator/(Dual<S> a, const Dual<S>& b) { return a /= b; }
template <typename S> constexpr Dual<S> operator-(const Dual<S>& a) { return {-a.v, -a.d}; }
template <typename S> constexpr Dual<S> operator+(Dual<S> a, S b) { a.v += b; return a; }
template <typename S> constexpr Dual<S> operator+(S b, Dual<S> a) { a.v += b; return a; }
template <typename S> constexpr Dual<S> operator-(Dual<S> a, S b) { a.v -= b; return a; }
template <typename S> constexpr Dual<S> operator-(S b, const Dual<S>& a) { return {b - a.v, -a.d}; }
template <typename S> constexpr Dual<S> operator*(Dual<S> a, S b) { a.v *= b; a.d *= b; return a; }
template <typename S> constexpr Dual<S> operator*(S b, Dual<S> a) { a.v *= b; a.d *= b; return a; }
template <typename S> constexpr Dual<S> operator/(Dual<S> a, S b) { a.v /= b; a.d /= b; return a; }
template <typename S> constexpr Dual<S> operator/(S b, const Dual<S>& a) {
  const S inv = S(1) / a.v;
  return {b * inv, -b * inv * inv * a.d};
}
template <typename S> constexpr bool operator<(const Dual<S>& a, const Dual<S>& b) { return a.v < b.v; }
template <typename S> constexpr bool operator>(const Dual<S>& a, const Dual<S>& b) { return a.v > b.v; }

template <typename S> Dual<S> exp(const Dual<S>& a) { const S e = std::exp(a.v); return {e, e * a.d}; }
template <typename S> Dual<S> log(const Dual<S>& a) { return {std::log(a.v), a.d / a.v}; }
template <typename S> Dual<S> sqrt(const Dual<S>& a) {
  const S s = std::sqrt(a.v);
  return {s, a.d / (S(2) * s)};
}
template <typename S> Dual<S> tanh(const Dual<S>& a) {
  const S t = std::tanh(a.v);
  return {t, (S(1) - t * t) * a.d};
}
template <typename S> Dual<S> sinh(const Dual<S>& a) { return {std::sinh(a.v), std::cosh(a.v) * a.d}; }
template <typename S> Dual<S> cosh(const Dual<S>& a) { return {std::cosh(a.v), std::sinh(a.v) * a.d}; }
template <typename S> Dual<S> pow(const Dual<S>& a, S p) {
  const S base = std::pow(a.v, p - S(1));
  return {base * a.v, p * base * a.d};
}

// Value of a plain scalar or of a dual number, for code templated on either.
template <typename S> constexpr S value_of(S x) { return x; }
template <typename S> constexpr S value_of(const Dual<S>& x) { return x.v; }

}  // namespace bms::fw
