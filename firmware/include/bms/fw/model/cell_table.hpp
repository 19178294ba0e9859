#pragma once
// A function of one variable as the firmware's cell configuration holds it: values and slopes
// at N uniformly spaced nodes, evaluated by cubic Hermite interpolation (C1, so the CV step's
// Newton iteration sees a continuous derivative), linear beyond the end nodes. The generator
// (`bmssim cell-config`, host_sim/src/cell/reduced_cell_record.cpp) fills it from a BPX
// expression or table and states its largest error over the cell's operating range.
// Templated on the number type: double, float and the dual numbers of the CV step.
// Firmware rules: fixed size, no heap, no exceptions.
#include <type_traits>

#include "bms/fw/model/dual.hpp"

namespace bms::fw {

// Version of the generated cell configuration's layout (the traits' fields and this table):
// a generated header states the version it was written for and fails to compile on another.
inline constexpr int kCellConfigSchema = 3;

template <int N>
struct HermiteTable {
  static_assert(N >= 2, "a table needs at least two nodes");
  static constexpr int kNodes = N;
  double x_first;
  double x_last;
  double y[N];
  double dydx[N];

  constexpr double step() const { return (x_last - x_first) / (N - 1); }

  template <typename T>
  T operator()(const T& x) const {
    using S = decltype(value_of(x));
    if constexpr (!std::is_same<S, double>::value) return single(x);
    const double h = step();
    const double xv = static_cast<double>(value_of(x));
    if (!(xv > x_first)) return T(S(y[0])) + (x - S(x_first)) * S(dydx[0]);
    if (!(xv < x_last)) return T(S(y[N - 1])) + (x - S(x_last)) * S(dydx[N - 1]);
    int i = static_cast<int>((xv - x_first) / h);
    if (i > N - 2) i = N - 2;
    const T t = (x - S(x_first + h * i)) / S(h);
    const T one_minus = S(1) - t;
    const T t2 = t * t;
    const T om2 = one_minus * one_minus;
    const T h00 = (S(1) + S(2) * t) * om2;
    const T h10 = t * om2;
    const T h01 = t2 * (S(3) - S(2) * t);
    const T h11 = t2 * (t - S(1));
    return h00 * S(y[i]) + h10 * S(h * dydx[i]) + h01 * S(y[i + 1]) + h11 * S(h * dydx[i + 1]);
  }

 private:
  // The same interpolation in the build's single precision (the Cortex-M4F's float): no double
  // arithmetic (software on that core), only the table's numbers converted to float. The node
  // index and the local coordinate lose about 1e-7 relative, below float's own resolution of
  // the result.
  template <typename T>
  T single(const T& x) const {
    using S = decltype(value_of(x));
    const S x0 = static_cast<S>(x_first);
    const S x1 = static_cast<S>(x_last);
    const S inv_h = static_cast<S>(N - 1) / (x1 - x0);
    const S h = (x1 - x0) / static_cast<S>(N - 1);
    const S xv = value_of(x);
    if (!(xv > x0)) return T(static_cast<S>(y[0])) + (x - x0) * static_cast<S>(dydx[0]);
    if (!(xv < x1)) return T(static_cast<S>(y[N - 1])) + (x - x1) * static_cast<S>(dydx[N - 1]);
    int i = static_cast<int>((xv - x0) * inv_h);
    if (i > N - 2) i = N - 2;
    const T t = (x - (x0 + h * static_cast<S>(i))) * inv_h;
    const T one_minus = S(1) - t;
    const T t2 = t * t;
    const T om2 = one_minus * one_minus;
    const T h00 = (S(1) + S(2) * t) * om2;
    const T h10 = t * om2;
    const T h01 = t2 * (S(3) - S(2) * t);
    const T h11 = t2 * (t - S(1));
    return h00 * static_cast<S>(y[i]) + h10 * (h * static_cast<S>(dydx[i])) + h01 * static_cast<S>(y[i + 1]) +
           h11 * (h * static_cast<S>(dydx[i + 1]));
  }
};

}  // namespace bms::fw
