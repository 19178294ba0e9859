// Offline RLS with P(0) = 1e10 on recorded DFN data recovers the true theta
// of the film subsystem (the paper's figure 7). The record is the truth model's own film
// resistance u and side-reaction current y0 over the CC charge of one paper cycle; the true
// theta comes from the film equation's parameters: R(k+1) = R(k) - T M / (a rho F kappa) J_s(k).
#include <gtest/gtest.h>

#include <cstdio>
#include <vector>

#include <bms/fw/estimation/rls_arx.hpp>

#include "cell/paper_cell.hpp"
#include "dfn/dfn_model.hpp"
#include "sim/cycler.hpp"

namespace {

using namespace bms;

TEST(OfflineRlsOnDfnData, LargeP0RecoversTheTrueThetaOfTheFilm) {
  const CellParameters cell = make_paper_cell();
  SimulationConfig cfg;
  cfg.cell = cell;
  cfg.temperature_k = cell.thermal.ambient_temperature_k;
  cfg.ic = default_initial_conditions(cell);
  CccvProtocol protocol;
  protocol.cycles = 1;
  protocol.v_min = cell.lower_voltage_v;
  protocol.v_max = cell.upper_voltage_v;
  const SimulationResult r = run_cccv(cfg, protocol);

  std::vector<double> u, y0;
  for (const auto& s : r.samples) {
    if (s.mode != Mode::cc_charge) continue;
    u.push_back(s.r_film_ohm_m2);
    y0.push_back(s.j_s_a_m3);
  }
  ASSERT_GT(u.size(), 10000u);  // about an hour of 0.2 s samples

  const DfnModel model(cell, DfnMesh{}, cfg.temperature_k);
  const double n1_true = -0.2 * model.film_growth_factor() / cell.negative.surface_area_per_volume_m();

  fw::RlsArxFit<double, 1>::Config config;
  config.p0_diag.setConstant(1e10);
  config.theta0.setZero();
  fw::RlsArxFit<double, 1> fit(config);
  EXPECT_EQ(fw::rls_fit_arx_offline(fit, u.data(), y0.data(), u.size()), 0u);
  const auto theta = fit.theta();
  std::printf("offline RLS, P0 = 1e10, %zu CC-charge samples of the truth: M1 = %.10f, N1 = %.4e (true 1, %.4e)\n",
              u.size(), theta(0), theta(1), n1_true);
  EXPECT_NEAR(theta(0), 1.0, 1e-7);
  EXPECT_NEAR(theta(1) / n1_true, 1.0, 0.05);
}

}  // namespace
