#pragma once
// Bounded one-dimensional minimisation for the candidates' single parameters. Each objective
// evaluation is a full DFN run, so the search is frugal: a coarse grid finds the basin (the
// RMSE of a misplaced knee can have side minima), golden-section search refines inside it.
#include <functional>

namespace bms::diagnosis {

struct MinimiseResult {
  double x = 0.0;
  double f = 0.0;
  int evaluations = 0;
};

// Minimises f on [lo, hi] to an absolute tolerance tol in x. grid_points >= 3.
MinimiseResult minimise_bounded(const std::function<double(double)>& f, double lo, double hi, double tol,
                                int grid_points = 7);

}  // namespace bms::diagnosis
