#pragma once
// The host's order statistics, written once: no data has no median (NaN), never 0 and never
// undefined behaviour; callers that want another answer for no data say so where they call.
#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace bms::stats {

/// The q-quantile (0 <= q <= 1) as the element at floor(q (n - 1)) of the sorted values; NaN when v is empty.
inline double quantile(std::vector<double> v, double q) {
  if (v.empty()) return std::nan("");
  const auto k = v.begin() + static_cast<std::ptrdiff_t>(q * static_cast<double>(v.size() - 1));
  std::nth_element(v.begin(), k, v.end());
  return *k;
}

/// The median as the element at n / 2 of the sorted values (the upper one of an even count);
/// NaN when v is empty.
inline double median(std::vector<double> v) {
  if (v.empty()) return std::nan("");
  const auto mid = v.begin() + static_cast<std::ptrdiff_t>(v.size() / 2);
  std::nth_element(v.begin(), mid, v.end());
  return *mid;
}

}  // namespace bms::stats
