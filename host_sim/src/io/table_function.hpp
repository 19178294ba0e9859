#pragma once
// BPX {"x": [...], "y": [...]} tables: piecewise-linear in x, held constant beyond the ends.
#include <string_view>
#include <vector>

#include "cell/scalar_function.hpp"

namespace bms {

class TableFunction final : public ScalarFunction {
 public:
  // Throws InputError naming `where` unless x and y have the same length (>= 2), x strictly
  // increases and every value is finite.
  TableFunction(std::vector<double> x, std::vector<double> y, std::string_view where);

  double value(double x) const override;
  // Slope of the segment holding x (at a knot the segment to its right, at the last knot the
  // last segment); 0 beyond the ends.
  double derivative(double x) const override;

  const std::vector<double>& x() const { return x_; }
  const std::vector<double>& y() const { return y_; }

 private:
  std::size_t segment(double x) const;
  double slope(std::size_t i) const { return (y_[i + 1] - y_[i]) / (x_[i + 1] - x_[i]); }

  std::vector<double> x_;
  std::vector<double> y_;
};

}  // namespace bms
