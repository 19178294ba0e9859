#include "baselines/baseline_run.hpp"

#include <chrono>
#include <cmath>
#include <limits>

#include <fmt/format.h>

#include "bms/fw/model/paper_cell.hpp"
#include "io/input_error.hpp"

namespace bms::baselines {

namespace {

void check_options(const BaselineOptions& o) {
  if (o.method != "ekf" && o.method != "batch" && o.method != "crlb")
    throw InputError(fmt::format("--method must be ekf, batch or crlb (got '{}')", o.method));
  if (o.sigma_v_v >= 0.0 && !(o.sigma_v_v > 0.0 && std::isfinite(o.sigma_v_v)))
    throw InputError("--noise-v-mv must be a positive number (the bound and the weights divide by it)");
  if (o.sigma_i_a >= 0.0 && !std::isfinite(o.sigma_i_a)) throw InputError("--noise-i-ma must be a finite number >= 0");
  if (!std::isfinite(o.r_film_init_ohm_m2) || o.r_film_init_ohm_m2 > 1.0)
    throw InputError("--r-film-init must be a film resistance in [0, 1] ohm m2");
  const auto& e = o.ekf;
  if (!(e.q_r_ohm_m2_per_sqrt_s >= 0.0) || !std::isfinite(e.q_r_ohm_m2_per_sqrt_s))
    throw InputError("--ekf-q-r must be a finite number >= 0");
  if (!(e.q_conc_rel_per_sqrt_s >= 0.0) || !std::isfinite(e.q_conc_rel_per_sqrt_s))
    throw InputError("--ekf-q-conc must be a finite number >= 0");
  if (!(e.gate_sigmas >= 0.0) || !std::isfinite(e.gate_sigmas))
    throw InputError("--ekf-gate must be a finite number >= 0 (0: no gate)");
  if (!(e.model_error_v >= 0.0) || !std::isfinite(e.model_error_v))
    throw InputError("--ekf-model-error-mv must be a finite number >= 0");
  if (!(e.p0_r_rel > 0.0) || !std::isfinite(e.p0_r_rel)) throw InputError("--ekf-p0-r must be a positive number");
  if (!(e.p0_conc_rel > 0.0) || !std::isfinite(e.p0_conc_rel))
    throw InputError("--ekf-p0-conc must be a positive number");
}

}  // namespace

BaselineResult run_baseline(const EstimateData& data, const BaselineOptions& o) {
  check_options(o);
  const auto wall0 = std::chrono::steady_clock::now();
  const Track track = make_track(data, fw::paper::kUpperVoltage_v, fw::paper::kLowerVoltage_v);
  Cell cell;
  cell.init(o.ic.stoich_neg, o.ic.stoich_pos, o.ic.electrolyte_mol_m3);
  const double r0 = o.r_film_init_ohm_m2 >= 0.0 ? o.r_film_init_ohm_m2 : fw::paper::kInitialFilm_ohm_m2;

  BaselineResult res;
  res.method = o.method;
  res.noise = choose_noise(track, o.sigma_v_v, o.sigma_i_a);
  const BoundRun bound = cramer_rao_bound(track, res.noise, cell, r0);
  res.bounds = bound.cycles;

  const std::size_t n = track.size();
  const double nan = std::numeric_limits<double>::quiet_NaN();
  std::vector<double> est(n, nan), sigma(n, nan);
  std::vector<double> model_v = bound.model_voltage_v;
  if (o.method == "ekf") {
    EkfRun r = run_ekf(track, res.noise, o.ekf, cell, r0);
    est = std::move(r.r_est);
    sigma = std::move(r.r_sigma);
    model_v = std::move(r.model_voltage_v);
    res.ekf_updates = r.updates;
    res.ekf_gated = r.gated;
  } else if (o.method == "batch") {
    BatchRun r = run_batch(track, res.noise, o.batch, cell, r0);
    est = std::move(r.r_est);
    sigma = std::move(r.r_sigma);
    model_v = std::move(r.model_voltage_v);
    res.batch_cycles = std::move(r.cycles);
  } else {
    // The bound of the cycle on every CC-charge tick of it: the std no unbiased estimate of
    // that cycle's film resistance can beat.
    std::size_t c = 0;
    for (const auto& [first, last] : track.cycles) {
      for (std::size_t i = first; i < last; ++i)
        if (track.mode[i] == fw::Mode::cc_charge) sigma[i] = res.bounds[c].bound_ohm_m2;
      ++c;
    }
  }

  res.rows.resize(n);
  res.r_sigma_ohm_m2 = std::move(sigma);
  for (std::size_t i = 0; i < n; ++i) {
    EstimateRow& r = res.rows[i];
    r.t_s = data.t_s[i];
    r.cycle = data.cycle[i];
    r.mode = track.mode[i];
    r.rcsi_active = false;
    r.r_film_est_ohm_m2 = est[i];
    r.r_film_true_ohm_m2 = data.r_film_true_ohm_m2.empty() ? std::nan("") : data.r_film_true_ohm_m2[i];
    r.model_voltage_v = model_v[i];
    r.z_v = model_v[i] - data.voltage_v[i];
  }
  if (o.method != "crlb") res.scores = score_cycles(res.rows, !data.true_mode.empty(), data.true_mode);
  res.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  return res;
}

}  // namespace bms::baselines
