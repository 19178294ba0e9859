// The retrospective step: scalar closed form and the general fixed-size form (eq 42).
#include <gtest/gtest.h>

#include <cmath>
#include <random>

#include <Eigen/Cholesky>
#include <Eigen/Core>

#include <bms/fw/estimation/rcsi_retrospective.hpp>

namespace {

using bms::fw::rcsi_cholesky_solve;
using bms::fw::rcsi_retrospective_inputs;
using bms::fw::rcsi_retrospective_u_star;
using bms::fw::rcsi_retrospective_z_star;

TEST(RcsiRetrospective, ScalarEtaZeroZeroesRetrospectivePerformance) {
  // z = H (u_applied - u_true): u* must be u_true, z* = 0. Sign: H > 0 and z > 0 (model
  // output too high) -> u* below u_applied.
  const double h = 0.01;
  const double u_applied = 3.5e-3;
  const double u_true = 3.4e-3;
  const double z = h * (u_applied - u_true);
  const double u_star = rcsi_retrospective_u_star(u_applied, z, h, 0.0);
  EXPECT_NEAR(u_star, u_true, 1e-18);
  EXPECT_LT(u_star, u_applied);
  EXPECT_NEAR(rcsi_retrospective_z_star(z, h, u_applied, u_star), 0.0, 1e-20);
  // With the opposite sign of H (discharge), the same z moves u* the other way.
  EXPECT_GT(rcsi_retrospective_u_star(u_applied, z, -h, 0.0), u_applied);
}

TEST(RcsiRetrospective, ScalarRegularisedMinimisesCost) {
  const double h = 0.7;
  const double eta = 0.3;
  const double u_applied = 1.2;
  const double z = 0.4;
  const double u_star = rcsi_retrospective_u_star(u_applied, z, h, eta);
  auto cost = [&](double u) {
    const double zs = rcsi_retrospective_z_star(z, h, u_applied, u);
    return zs * zs + eta * u * u;
  };
  EXPECT_LT(cost(u_star), cost(u_star + 1e-4));
  EXPECT_LT(cost(u_star), cost(u_star - 1e-4));
  // Stationarity: d/du [(z - h u_a + h u)^2 + eta u^2] = 0.
  EXPECT_NEAR(2.0 * h * rcsi_retrospective_z_star(z, h, u_applied, u_star) + 2.0 * eta * u_star,
              0.0, 1e-15);
}

TEST(RcsiRetrospective, GeneralFormMatchesScalarForm) {
  for (const double eta : {0.0, 0.05, 2.0}) {
    Eigen::Matrix<double, 1, 1> h;
    h << -0.3;
    Eigen::Matrix<double, 1, 1> r;
    r << 1.0;
    Eigen::Matrix<double, 1, 1> z;
    z << 0.02;
    Eigen::Matrix<double, 1, 1> u;
    u << 0.5;
    Eigen::Matrix<double, 1, 1> u_star;
    ASSERT_TRUE(rcsi_retrospective_inputs(h, r, eta, z, u, u_star));
    EXPECT_NEAR(u_star(0), rcsi_retrospective_u_star(0.5, 0.02, -0.3, eta), 1e-14) << eta;
  }
}

TEST(RcsiRetrospective, GeneralFormRecoversTrueInputsWithFullRankH) {
  // Z = S + H U with S unknown; if Z was produced by U_true with S = 0, i.e.
  // Z = H (U - U_true) relative to the applied U, then U* = U_true exactly (eta = 0).
  std::mt19937 rng(11u);
  std::normal_distribution<double> normal(0.0, 1.0);
  Eigen::Matrix<double, 3, 2> h;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 2; ++j) {
      h(i, j) = normal(rng);
    }
  }
  Eigen::Matrix3d r = Eigen::Matrix3d::Identity();
  r(1, 1) = 4.0;
  const Eigen::Vector2d u_applied(0.3, -0.7);
  const Eigen::Vector2d u_true(0.25, -0.4);
  const Eigen::Vector3d z = h * (u_applied - u_true);
  Eigen::Vector2d u_star;
  ASSERT_TRUE(rcsi_retrospective_inputs(h, r, 0.0, z, u_applied, u_star));
  EXPECT_LT((u_star - u_true).cwiseAbs().maxCoeff(), 1e-14);
}

TEST(RcsiRetrospective, GeneralFormRejectsRankDeficientWithoutRegularisation) {
  Eigen::Matrix<double, 2, 2> h;
  h << 1.0, 0.0, 2.0, 0.0;  // second input has no effect on Z
  const Eigen::Matrix2d r = Eigen::Matrix2d::Identity();
  const Eigen::Vector2d z(0.1, 0.2);
  const Eigen::Vector2d u(1.0, 2.0);
  Eigen::Vector2d u_star(42.0, 42.0);
  EXPECT_FALSE(rcsi_retrospective_inputs(h, r, 0.0, z, u, u_star));
  EXPECT_EQ(u_star, Eigen::Vector2d(42.0, 42.0));
  // eta > 0 makes the problem well posed; the uncontrolled input is driven to 0.
  ASSERT_TRUE(rcsi_retrospective_inputs(h, r, 0.1, z, u, u_star));
  EXPECT_EQ(u_star(1), 0.0);
}

TEST(RcsiRetrospective, CholeskySolveMatchesEigenLlt) {
  std::mt19937 rng(5u);
  std::normal_distribution<double> normal(0.0, 1.0);
  for (int trial = 0; trial < 20; ++trial) {
    Eigen::Matrix<double, 6, 6> m;
    Eigen::Matrix<double, 6, 1> b;
    for (int i = 0; i < 6; ++i) {
      b(i) = normal(rng);
      for (int j = 0; j < 6; ++j) {
        m(i, j) = normal(rng);
      }
    }
    const Eigen::Matrix<double, 6, 6> a =
        m * m.transpose() + 0.1 * Eigen::Matrix<double, 6, 6>::Identity();
    Eigen::Matrix<double, 6, 1> x = b;
    ASSERT_TRUE((rcsi_cholesky_solve<double, 6>(a, x)));
    const Eigen::Matrix<double, 6, 1> reference = a.llt().solve(b);  // test code only
    EXPECT_LT((x - reference).cwiseAbs().maxCoeff(), 1e-10 * (1.0 + reference.norm()));
    EXPECT_LT((a * x - b).cwiseAbs().maxCoeff(), 1e-10);
  }
  // Not positive definite: rejected, right-hand side untouched.
  Eigen::Matrix2d indefinite;
  indefinite << 1.0, 2.0, 2.0, 1.0;
  Eigen::Vector2d rhs(1.0, 1.0);
  EXPECT_FALSE((rcsi_cholesky_solve<double, 2>(indefinite, rhs)));
  EXPECT_EQ(rhs, Eigen::Vector2d(1.0, 1.0));
}

}  // namespace
