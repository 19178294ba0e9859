#include "io/table_function.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>

#include "io/input_error.hpp"

namespace bms {

TableFunction::TableFunction(std::vector<double> x, std::vector<double> y, std::string_view where)
    : x_(std::move(x)), y_(std::move(y)) {
  if (x_.size() != y_.size()) {
    throw InputError(
        fmt::format("{}: table has {} x values but {} y values", where, x_.size(), y_.size()));
  }
  if (x_.size() < 2) {
    throw InputError(fmt::format("{}: table needs at least 2 points, has {}", where, x_.size()));
  }
  for (std::size_t i = 0; i < x_.size(); ++i) {
    if (!std::isfinite(x_[i]) || !std::isfinite(y_[i])) {
      throw InputError(
          fmt::format("{}: table point {} (x = {}, y = {}) is not finite", where, i, x_[i], y_[i]));
    }
    if (i > 0 && !(x_[i] > x_[i - 1])) {
      throw InputError(
          fmt::format("{}: table x must strictly increase, but x[{}] = {} follows "
                      "x[{}] = {}",
                      where, i, x_[i], i - 1, x_[i - 1]));
    }
  }
}

std::size_t TableFunction::segment(double x) const {
  const auto it = std::upper_bound(x_.begin(), x_.end(), x);
  const auto i = static_cast<std::size_t>(std::max<std::ptrdiff_t>(it - x_.begin() - 1, 0));
  return std::min(i, x_.size() - 2);
}

double TableFunction::value(double x) const {
  if (x <= x_.front()) return y_.front();
  if (x >= x_.back()) return y_.back();
  const std::size_t i = segment(x);  // NaN lands here and propagates
  return y_[i] + slope(i) * (x - x_[i]);
}

double TableFunction::derivative(double x) const {
  if (x < x_.front() || x > x_.back()) return 0.0;
  if (std::isnan(x)) return x;
  return slope(segment(x));
}

}  // namespace bms
