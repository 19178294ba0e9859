#include "baselines/batch_fit.hpp"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Dense>

namespace bms::baselines {

namespace {

struct Window {
  std::size_t first = 0, last = 0;  // [first, last): first to last CC-charge tick of the cycle
  double t_mid_s = 0.0, half_span_s = 1.0;
  double tau(const Track& t, std::size_t i) const { return (t.data->t_s[i] - t_mid_s) / half_span_s; }
};

double film_at(const Window& w, const Track& t, std::size_t i, const Eigen::Vector2d& p) {
  return p(0) + p(1) * w.tau(t, i);
}

// Model voltage over the window for parameters p, on a copy of the model at the window start.
std::vector<double> window_voltage(const Cell& at_start, const Track& t, const Window& w, const Eigen::Vector2d& p) {
  Cell c = at_start;
  std::vector<double> v(w.last - w.first);
  for (std::size_t i = w.first; i < w.last; ++i) v[i - w.first] = step(c, t, i, film_at(w, t, i, p)).voltage_v;
  return v;
}

// Weights from the tick's own current sensitivity (barely depends on R_film), on a copy of the
// model at the window start; 0 outside CC charge.
std::vector<double> window_weights(const Cell& at_start, const Track& t, const Window& w, double r_hold, double var_v,
                                   double var_i) {
  std::vector<double> weight(w.last - w.first, 0.0);
  Cell c = at_start;
  for (std::size_t i = w.first; i < w.last; ++i) {
    if (t.mode[i] == fw::Mode::cc_charge) {
      const OutputSensitivity s = output_sensitivity(c, t, i, r_hold);
      weight[i - w.first] = 1.0 / (var_v + var_i * s.dv_di_v_per_a * s.dv_di_v_per_a);
    }
    step(c, t, i, r_hold);
  }
  return weight;
}

// Gauss-Newton on the window's weighted voltage error, from p (updated in place); np = 1 holds
// the slope at 0. Returns the last normal matrix (its inverse is the parameters' covariance).
Eigen::Matrix2d fit_window(const Cell& cell, const Track& t, const Window& w, const std::vector<double>& weight, int np,
                           int max_iterations, Eigen::Vector2d& p, int& iterations) {
  const EstimateData& d = *t.data;
  Eigen::Matrix2d normal = Eigen::Matrix2d::Identity();
  std::vector<double> v;
  for (int it = 0; it < max_iterations; ++it) {
    v = window_voltage(cell, t, w, p);
    std::vector<double> jac[2];
    for (int k = 0; k < np; ++k) {
      Eigen::Vector2d pk = p;
      pk(k) += kFilmStepOhmM2;
      jac[k] = window_voltage(cell, t, w, pk);
      for (std::size_t n = 0; n < v.size(); ++n) jac[k][n] = (jac[k][n] - v[n]) / kFilmStepOhmM2;
    }
    normal.setZero();
    Eigen::Vector2d grad = Eigen::Vector2d::Zero();
    for (std::size_t n = 0; n < v.size(); ++n) {
      const double wn = weight[n];
      if (wn == 0.0) continue;
      const double e = v[n] - d.voltage_v[w.first + n];
      for (int a = 0; a < np; ++a) {
        grad(a) += wn * jac[a][n] * e;
        for (int b = 0; b < np; ++b) normal(a, b) += wn * jac[a][n] * jac[b][n];
      }
    }
    if (np == 1) normal(1, 1) = 1.0;  // the slope stays 0
    const Eigen::Vector2d delta = -normal.ldlt().solve(grad);
    p += delta;
    iterations = it + 1;
    const double sigma_a = 1.0 / std::sqrt(normal(0, 0));
    if (std::abs(delta(0)) < 1e-3 * sigma_a && std::abs(delta(1)) < 1e-3 * sigma_a) break;
  }
  return normal;
}

}  // namespace

BatchRun run_batch(const Track& t, const NoiseLevels& noise, const BatchConfig& config, Cell cell,
                   double r_film_init_ohm_m2) {
  const EstimateData& d = *t.data;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  BatchRun out;
  out.r_est.assign(t.size(), nan);
  out.r_sigma.assign(t.size(), nan);
  out.model_voltage_v.assign(t.size(), nan);
  const int np = config.linear ? 2 : 1;
  const double var_v = noise.sigma_v_v * noise.sigma_v_v, var_i = noise.sigma_i_a * noise.sigma_i_a;
  double r_hold = r_film_init_ohm_m2, sigma_hold = nan;

  auto drive = [&](std::size_t from, std::size_t to) {
    for (std::size_t i = from; i < to; ++i) {
      out.model_voltage_v[i] = step(cell, t, i, r_hold).voltage_v;
      out.r_est[i] = r_hold;
      out.r_sigma[i] = sigma_hold;
    }
  };

  for (const auto& [first, last] : t.cycles) {
    Window w;
    w.first = last;
    for (std::size_t i = first; i < last; ++i) {
      if (t.mode[i] != fw::Mode::cc_charge) continue;
      if (w.first == last) w.first = i;
      w.last = i + 1;
    }
    if (w.first == last) {  // no CC charge: nothing to fit in this cycle
      drive(first, last);
      continue;
    }
    drive(first, w.first);
    w.t_mid_s = 0.5 * (d.t_s[w.first] + d.t_s[w.last - 1]);
    w.half_span_s = std::max(0.5 * (d.t_s[w.last - 1] - d.t_s[w.first]), t.dt_s);

    const std::vector<double> weight = window_weights(cell, t, w, r_hold, var_v, var_i);
    Eigen::Vector2d p(r_hold, 0.0);
    BatchCycle bc;
    bc.cycle = d.cycle[first];
    const Eigen::Matrix2d normal = fit_window(cell, t, w, weight, np, config.max_iterations, p, bc.iterations);
    const Eigen::Matrix2d cov = normal.inverse();

    // Commit the fit: residual statistics and the state carried on.
    double sum_e = 0.0, sum_e2 = 0.0;
    for (std::size_t i = w.first; i < w.last; ++i) {
      const double r = film_at(w, t, i, p);
      const double vm = step(cell, t, i, r).voltage_v;
      out.model_voltage_v[i] = vm;
      out.r_est[i] = r;
      const Eigen::Vector2d g(1.0, np == 2 ? w.tau(t, i) : 0.0);
      out.r_sigma[i] = std::sqrt(std::max(g.dot(cov * g), 0.0));
      if (t.mode[i] == fw::Mode::cc_charge) {
        const double e = vm - d.voltage_v[i];
        sum_e += e;
        sum_e2 += e * e;
        ++bc.ticks;
      }
    }
    bc.r_a_ohm_m2 = p(0);
    bc.r_b_ohm_m2 = p(1);
    bc.sigma_a_ohm_m2 = std::sqrt(cov(0, 0));
    bc.mean_residual_v = sum_e / static_cast<double>(bc.ticks);
    bc.rms_residual_v = std::sqrt(sum_e2 / static_cast<double>(bc.ticks));
    out.cycles.push_back(bc);
    r_hold = out.r_est[w.last - 1];
    sigma_hold = out.r_sigma[w.last - 1];
    drive(w.last, last);
  }
  return out;
}

}  // namespace bms::baselines
