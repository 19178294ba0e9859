#include "diagnosis/minimise.hpp"

#include <cmath>
#include <stdexcept>
#include <vector>

namespace bms::diagnosis {

MinimiseResult minimise_bounded(const std::function<double(double)>& f, double lo, double hi, double tol,
                                int grid_points) {
  if (!(hi > lo) || !(tol > 0.0) || grid_points < 3) throw std::invalid_argument("minimise_bounded: bad bracket");
  MinimiseResult best;
  best.f = INFINITY;
  auto eval = [&](double x) {
    const double v = f(x);
    ++best.evaluations;
    if (v < best.f) {
      best.f = v;
      best.x = x;
    }
    return v;
  };
  const double step = (hi - lo) / (grid_points - 1);
  std::vector<double> fx(static_cast<std::size_t>(grid_points));
  int ibest = 0;
  for (int k = 0; k < grid_points; ++k) {
    fx[static_cast<std::size_t>(k)] = eval(lo + step * k);
    if (fx[static_cast<std::size_t>(k)] < fx[static_cast<std::size_t>(ibest)]) ibest = k;
  }
  // Golden section on the two grid intervals around the best grid point.
  double a = lo + step * std::max(0, ibest - 1);
  double b = lo + step * std::min(grid_points - 1, ibest + 1);
  const double g = 0.5 * (std::sqrt(5.0) - 1.0);
  double c = b - g * (b - a), d = a + g * (b - a);
  double fc = eval(c), fd = eval(d);
  while (b - a > tol) {
    if (fc < fd) {
      b = d;
      d = c;
      fd = fc;
      c = b - g * (b - a);
      fc = eval(c);
    } else {
      a = c;
      c = d;
      fc = fd;
      d = a + g * (b - a);
      fd = eval(d);
    }
  }
  return best;
}

}  // namespace bms::diagnosis
