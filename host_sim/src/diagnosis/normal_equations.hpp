#pragma once
// The small least-squares pieces both fits share (diagnose's effect knobs, fit's cell
// parameters): a Jacobian as columns of residuals, and its normal equations J^T J and J^T r in
// matrices of bounded size (the host links the firmware's EIGEN_NO_MALLOC: nothing here may
// allocate an Eigen object on the heap).
#include <algorithm>
#include <cstddef>
#include <vector>

#include <Eigen/Dense>

namespace bms::diagnosis {

using Columns = std::vector<std::vector<double>>;  // one Jacobian column per parameter

template <int MaxN>
using BoundedMatrix = Eigen::Matrix<double, Eigen::Dynamic, Eigen::Dynamic, 0, MaxN, MaxN>;
template <int MaxN>
using BoundedVector = Eigen::Matrix<double, Eigen::Dynamic, 1, 0, MaxN, 1>;

inline double dot(const std::vector<double>& a, const std::vector<double>& b) {
  double d = 0.0;
  for (std::size_t i = 0; i < std::min(a.size(), b.size()); ++i) d += a[i] * b[i];
  return d;
}

// J^T J.
template <int MaxN>
BoundedMatrix<MaxN> gram(const Columns& J) {
  const auto n = static_cast<Eigen::Index>(J.size());
  BoundedMatrix<MaxN> g(n, n);
  for (Eigen::Index a = 0; a < n; ++a)
    for (Eigen::Index b = 0; b <= a; ++b)
      g(a, b) = g(b, a) = dot(J[static_cast<std::size_t>(a)], J[static_cast<std::size_t>(b)]);
  return g;
}

// J^T r.
template <int MaxN>
BoundedVector<MaxN> gradient(const Columns& J, const std::vector<double>& r) {
  BoundedVector<MaxN> g(static_cast<Eigen::Index>(J.size()));
  for (std::size_t c = 0; c < J.size(); ++c) g(static_cast<Eigen::Index>(c)) = dot(J[c], r);
  return g;
}

}  // namespace bms::diagnosis
