#pragma once
// Retrospective step of RCSI (paper eqs 30-42, clean form in models.md section 4).
//
// With z = y_hat - y and H the Markov parameter(s) from u_hat to z, the retrospective
// performance of surrogate past inputs U* is (eq 36)
//   Z* = Z - H U + H U*,
// and U* minimises Z*^T R Z* + eta U*^T U* (eq 37):
//   U* = -(H^T R H + eta I)^-1 H^T R (Z - H U)                              (eq 42)
// Scalar case (one z, one u, R = 1 without loss of generality since only eta/R matters):
//   u* = (H^2 u - H z) / (H^2 + eta),   and for eta = 0 exactly  u* = u - z / H.
// Sign: H = dz/du_hat = +d y_hat/d u_hat (because z = y_hat - y). With a wrong sign of H
// the surrogate moves away from the value that would have zeroed z.
#include <cmath>

#include <Eigen/Core>

namespace bms::fw {

// Scalar retrospective input u*(k-d) from the applied u_hat(k-d), z(k), H and eta >= 0.
// The caller guarantees h != 0 when eta == 0.
template <typename Scalar>
Scalar rcsi_retrospective_u_star(Scalar u_applied, Scalar z, Scalar h, Scalar eta) {
  if (eta == Scalar(0)) {
    return u_applied - z / h;  // exact form of the paper's setting (eta = 0)
  }
  const Scalar h2 = h * h;
  return (h2 * u_applied - h * z) / (h2 + eta);
}

// Retrospective performance z*(k) = z(k) - H (u_applied - u*) for the scalar case (eq 36).
template <typename Scalar>
Scalar rcsi_retrospective_z_star(Scalar z, Scalar h, Scalar u_applied, Scalar u_star) {
  return z - h * (u_applied - u_star);
}

// Solves A x = b in place (b -> x) for a symmetric positive-definite fixed-size A by an
// unblocked Cholesky factorisation. Returns false (b unchanged) if a pivot is not positive
// or not finite. Hand-written rather than Eigen::LLT: Eigen's blocked code paths (dead for
// small fixed sizes, but compiled at -O0) reference the heap.
template <typename Scalar, int N>
bool rcsi_cholesky_solve(const Eigen::Matrix<Scalar, N, N>& a, Eigen::Matrix<Scalar, N, 1>& b) {
  Eigen::Matrix<Scalar, N, N> l = Eigen::Matrix<Scalar, N, N>::Zero();
  for (int j = 0; j < N; ++j) {
    Scalar pivot = a(j, j);
    for (int k = 0; k < j; ++k) {
      pivot -= l(j, k) * l(j, k);
    }
    if (!std::isfinite(pivot) || !(pivot > Scalar(0))) {
      return false;
    }
    l(j, j) = std::sqrt(pivot);
    for (int i = j + 1; i < N; ++i) {
      Scalar v = a(i, j);
      for (int k = 0; k < j; ++k) {
        v -= l(i, k) * l(j, k);
      }
      l(i, j) = v / l(j, j);
    }
  }
  Eigen::Matrix<Scalar, N, 1> x = b;
  for (int i = 0; i < N; ++i) {  // L y = b
    for (int k = 0; k < i; ++k) {
      x(i) -= l(i, k) * x(k);
    }
    x(i) /= l(i, i);
  }
  for (int i = N - 1; i >= 0; --i) {  // L^T x = y
    for (int k = i + 1; k < N; ++k) {
      x(i) -= l(k, i) * x(k);
    }
    x(i) /= l(i, i);
  }
  b = x;
  return true;
}

// General fixed-size form: Nz stacked performances Z, Nu surrogate inputs U (eq 42).
// R must be symmetric positive definite; H needs full column rank or eta > 0 (eq 42).
// Returns false (u_star untouched) when the Cholesky factorisation of H^T R H + eta I
// fails (e.g. an all-zero column of H with eta = 0) or the result is not finite.
template <typename Scalar, int Nz, int Nu>
bool rcsi_retrospective_inputs(const Eigen::Matrix<Scalar, Nz, Nu>& h,
                               const Eigen::Matrix<Scalar, Nz, Nz>& r, Scalar eta,
                               const Eigen::Matrix<Scalar, Nz, 1>& z,
                               const Eigen::Matrix<Scalar, Nu, 1>& u_applied,
                               Eigen::Matrix<Scalar, Nu, 1>& u_star) {
  static_assert(Nz >= 1 && Nz <= 16 && Nu >= 1 && Nu <= 16, "small fixed sizes only");
  using MatU = Eigen::Matrix<Scalar, Nu, Nu>;
  using VecU = Eigen::Matrix<Scalar, Nu, 1>;
  const Eigen::Matrix<Scalar, Nu, Nz> ht_r = h.transpose() * r;
  const MatU a = ht_r * h + eta * MatU::Identity();
  VecU solution = ht_r * (z - h * u_applied);  // B/2 of eq 40
  if (!rcsi_cholesky_solve<Scalar, Nu>(a, solution)) {
    return false;
  }
  solution = -solution;
  if (!solution.allFinite()) {
    return false;
  }
  u_star = solution;
  return true;
}

}  // namespace bms::fw
