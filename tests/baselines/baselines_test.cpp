// Baselines on data made by the reduced model itself with a known film resistance: there the
// model is exact, so the only error left is the noise, and the Cramer-Rao bound says how small
// it can be.
#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <string>

#include "baselines/baseline_run.hpp"
#include "baselines/crlb.hpp"
#include "baselines/noise_levels.hpp"
#include "bms/fw/model/paper_cell.hpp"
#include "io/input_error.hpp"

namespace bms::baselines {
namespace {

constexpr double kStoichNeg = 0.3, kStoichPos = 0.7;  // mid charge: 2.5 A charging stays below 3.6 V
constexpr double kChargeA = -2.5;

struct Synthetic {
  double sigma_v_v = 0.0, sigma_i_a = 0.0;
  double r_start_ohm_m2 = 0.0, r_end_ohm_m2 = 0.0;  // linear in time over the run
  std::size_t ticks = 2000;
  unsigned seed = 7;
};

// CC charge of the reduced model at 0.2 s ticks, film resistance known, noise added afterwards
// (the model runs on the true current, the file carries the measured one).
EstimateData make_data(const Synthetic& s) {
  Cell cell;
  cell.init(kStoichNeg, kStoichPos, fw::paper::kElectrolyteInit_mol_m3);
  std::mt19937 rng(s.seed);
  std::normal_distribution<double> nv(0.0, 1.0), ni(0.0, 1.0);
  EstimateData d;
  d.source = "synthetic";
  for (std::size_t k = 0; k < s.ticks; ++k) {
    const double f = s.ticks > 1 ? static_cast<double>(k) / static_cast<double>(s.ticks - 1) : 0.0;
    const double r = s.r_start_ohm_m2 + f * (s.r_end_ohm_m2 - s.r_start_ohm_m2);
    const auto out = cell.step_current(kChargeA, r, 0.2);
    d.t_s.push_back(0.2 * static_cast<double>(k));
    d.cycle.push_back(1);
    d.current_a.push_back(kChargeA + s.sigma_i_a * ni(rng));
    d.voltage_v.push_back(out.voltage_v + s.sigma_v_v * nv(rng));
    d.r_film_true_ohm_m2.push_back(r);
    d.true_mode.push_back(fw::Mode::cc_charge);
  }
  return d;
}

BaselineOptions options(const std::string& method, double sigma_v_v) {
  BaselineOptions o;
  o.method = method;
  o.sigma_v_v = sigma_v_v;
  o.sigma_i_a = 0.0;
  o.ic.stoich_neg = kStoichNeg;
  o.ic.stoich_pos = kStoichPos;
  o.ic.electrolyte_mol_m3 = fw::paper::kElectrolyteInit_mol_m3;
  o.r_film_init_ohm_m2 = fw::paper::kInitialFilm_ohm_m2;
  o.ekf.model_error_v = 0.0;  // the data come from the model itself
  return o;
}

// The film the estimators must find is 20 % above the one they start from.
constexpr double kTrueFilm = 1.2 * fw::paper::kInitialFilm_ohm_m2;

double end_error_ohm_m2(const BaselineResult& r) {
  const auto& last = r.rows.back();
  return last.r_film_est_ohm_m2 - last.r_film_true_ohm_m2;
}

TEST(Baselines, BatchRecoversTheFilmWithinTheNoise) {
  Synthetic s;
  s.sigma_v_v = 0.2e-3;
  s.r_start_ohm_m2 = s.r_end_ohm_m2 = kTrueFilm;
  const EstimateData d = make_data(s);
  const BaselineResult r = run_baseline(d, options("batch", s.sigma_v_v));
  ASSERT_EQ(r.bounds.size(), 1u);
  const double bound = r.bounds[0].bound_ohm_m2;
  // One unbiased estimate: within 4 sigma of the truth, and sigma is the bound (efficient).
  EXPECT_LT(std::abs(end_error_ohm_m2(r)), 4.0 * bound) << "bound " << bound;
  ASSERT_EQ(r.batch_cycles.size(), 1u);
  EXPECT_NEAR(r.batch_cycles[0].sigma_a_ohm_m2, bound, 0.05 * bound);
  // The noise is white and the model exact: the fit's residual is the noise.
  EXPECT_NEAR(r.batch_cycles[0].rms_residual_v, s.sigma_v_v, 0.1 * s.sigma_v_v);
}

TEST(Baselines, BatchLinearShapeFollowsAGrowingFilm) {
  Synthetic s;
  s.sigma_v_v = 0.02e-3;
  s.r_start_ohm_m2 = kTrueFilm;
  s.r_end_ohm_m2 = 1.05 * kTrueFilm;
  const EstimateData d = make_data(s);
  BaselineOptions o = options("batch", s.sigma_v_v);
  const BaselineResult constant = run_baseline(d, o);
  o.batch.linear = true;
  const BaselineResult linear = run_baseline(d, o);
  // A constant cannot follow a 5 % ramp (end error about 2.5 %); the linear shape can.
  EXPECT_GT(std::abs(end_error_ohm_m2(constant)), 0.01 * kTrueFilm);
  EXPECT_LT(std::abs(end_error_ohm_m2(linear)), 0.001 * kTrueFilm);
  EXPECT_NEAR(2.0 * linear.batch_cycles[0].r_b_ohm_m2, s.r_end_ohm_m2 - s.r_start_ohm_m2,
              0.02 * (s.r_end_ohm_m2 - s.r_start_ohm_m2));
}

TEST(Baselines, EkfConvergesFromTwentyPercentOff) {
  Synthetic s;
  s.sigma_v_v = 0.2e-3;
  s.r_start_ohm_m2 = s.r_end_ohm_m2 = kTrueFilm;
  const EstimateData d = make_data(s);
  const BaselineResult r = run_baseline(d, options("ekf", s.sigma_v_v));
  const double bound = r.bounds[0].bound_ohm_m2;
  const double sigma_end = r.r_sigma_ohm_m2.back();
  // Start: 20 % off (about 1e3 bounds); end: within the filter's own sigma. That sigma is
  // above the bound: the bound knows the model's state, the filter starts with an uncertain
  // state (P(0)), and a uniform concentration shift looks much like film resistance in CC.
  EXPECT_GT(std::abs(r.rows.front().r_film_est_ohm_m2 - kTrueFilm), 100.0 * bound);
  EXPECT_LT(std::abs(end_error_ohm_m2(r)), 4.0 * sigma_end) << "sigma " << sigma_end;
  EXPECT_GT(sigma_end, 0.7 * bound);
  EXPECT_LT(sigma_end, 0.02 * kTrueFilm);
  EXPECT_GT(r.ekf_updates, s.ticks - 10);  // learns in every CC-charge tick after the debounce
}

TEST(Baselines, EkfWithAKnownStateReachesTheBound) {
  Synthetic s;
  s.sigma_v_v = 0.2e-3;
  s.r_start_ohm_m2 = s.r_end_ohm_m2 = kTrueFilm;
  const EstimateData d = make_data(s);
  BaselineOptions o = options("ekf", s.sigma_v_v);
  o.ekf.p0_conc_rel = 1e-9;  // the state is known: only R_film is to be found, as in the bound
  const BaselineResult r = run_baseline(d, o);
  const double bound = r.bounds[0].bound_ohm_m2;
  const double sigma_end = r.r_sigma_ohm_m2.back();
  // Efficient up to the random walk the filter keeps on R_film (it forgets a little).
  EXPECT_GT(sigma_end, 0.7 * bound);
  EXPECT_LT(sigma_end, 2.0 * bound);
  EXPECT_LT(std::abs(end_error_ohm_m2(r)), 4.0 * sigma_end) << "bound " << bound;
}

TEST(Baselines, EkfWithCurrentNoiseStaysWithinItsBound) {
  Synthetic s;
  s.sigma_v_v = 0.02e-3;
  s.sigma_i_a = 5e-3;
  s.r_start_ohm_m2 = s.r_end_ohm_m2 = kTrueFilm;
  const EstimateData d = make_data(s);
  BaselineOptions o = options("ekf", s.sigma_v_v);
  o.sigma_i_a = s.sigma_i_a;
  const BaselineResult r = run_baseline(d, o);
  const double bound = r.bounds[0].bound_ohm_m2;
  EXPECT_LT(std::abs(end_error_ohm_m2(r)), 6.0 * bound) << "bound " << bound;
}

TEST(Baselines, BoundScalesAsSigmaOverRootN) {
  Synthetic s;
  s.r_start_ohm_m2 = s.r_end_ohm_m2 = kTrueFilm;
  s.ticks = 400;
  const EstimateData short_run = make_data(s);
  s.ticks = 1600;
  const EstimateData long_run = make_data(s);
  const BaselineResult a = run_baseline(short_run, options("crlb", 0.1e-3));
  const BaselineResult b = run_baseline(short_run, options("crlb", 0.2e-3));
  const BaselineResult c = run_baseline(long_run, options("crlb", 0.1e-3));
  const double ba = a.bounds[0].bound_ohm_m2;
  EXPECT_NEAR(b.bounds[0].bound_ohm_m2 / ba, 2.0, 1e-6);
  // Four times the samples (minus the same debounce) halves it; dV/dR_film = -j_n is constant.
  const double n_ratio = static_cast<double>(c.bounds[0].ticks) / static_cast<double>(a.bounds[0].ticks);
  EXPECT_NEAR(ba / c.bounds[0].bound_ohm_m2, std::sqrt(n_ratio), 1e-3);
  // And its size: sigma / (|j_n| sqrt(N)), j_n = I / (A a_n L_n), a_n = 3 eps_s / R_p.
  const auto& neg = fw::paper::kNegative;
  const double j_n = 2.5 / fw::paper::kElectrodeArea_m2 /
                     (3.0 * neg.solid_fraction / neg.particle_radius_m * neg.thickness_m);
  EXPECT_NEAR(ba, 0.1e-3 / (j_n * std::sqrt(static_cast<double>(a.bounds[0].ticks))), 1e-3 * ba);
  // The bound has no estimate to score.
  EXPECT_TRUE(a.scores.empty());
  EXPECT_TRUE(std::isnan(a.rows.back().r_film_est_ohm_m2));
}

TEST(Baselines, CurrentNoiseWidensTheBound) {
  Synthetic s;
  s.r_start_ohm_m2 = s.r_end_ohm_m2 = kTrueFilm;
  s.ticks = 400;
  const EstimateData d = make_data(s);
  BaselineOptions o = options("crlb", 0.02e-3);
  const double quiet = run_baseline(d, o).bounds[0].bound_ohm_m2;
  o.sigma_i_a = 5e-3;
  const double noisy = run_baseline(d, o).bounds[0].bound_ohm_m2;
  EXPECT_GT(noisy, 1.2 * quiet);
}

TEST(Baselines, NoiseIsEstimatedFromTheData) {
  Synthetic s;
  s.sigma_v_v = 0.2e-3;
  s.sigma_i_a = 5e-3;
  s.r_start_ohm_m2 = s.r_end_ohm_m2 = kTrueFilm;
  const EstimateData noisy = make_data(s);
  const Track t = make_track(noisy, 3.6, 2.0);
  const NoiseLevels n = choose_noise(t, -1.0, -1.0);
  EXPECT_EQ(n.v_source, "estimated");
  EXPECT_NEAR(n.sigma_v_v, s.sigma_v_v, 0.1 * s.sigma_v_v);
  EXPECT_NEAR(n.sigma_i_a, s.sigma_i_a, 0.1 * s.sigma_i_a);
  s.sigma_v_v = s.sigma_i_a = 0.0;
  const EstimateData clean = make_data(s);
  const NoiseLevels c = choose_noise(make_track(clean, 3.6, 2.0), -1.0, -1.0);
  EXPECT_EQ(c.v_source, "floor");
  EXPECT_DOUBLE_EQ(c.sigma_v_v, kVoltageNoiseFloorV);
  EXPECT_LT(c.sigma_i_a, 1e-9);
  const NoiseLevels given = choose_noise(make_track(clean, 3.6, 2.0), 0.5e-3, 1e-3);
  EXPECT_EQ(given.v_source, "option");
  EXPECT_DOUBLE_EQ(given.sigma_v_v, 0.5e-3);
}

TEST(Baselines, BadInputIsRejectedNamingTheField) {
  Synthetic s;
  s.r_start_ohm_m2 = s.r_end_ohm_m2 = kTrueFilm;
  s.ticks = 50;
  EstimateData d = make_data(s);
  auto message = [](const EstimateData& data, const BaselineOptions& o) -> std::string {
    try {
      run_baseline(data, o);
    } catch (const InputError& e) {
      return e.what();
    }
    return "";
  };
  EXPECT_NE(message(d, options("kalman", 0.1e-3)).find("--method"), std::string::npos);
  EXPECT_NE(message(d, options("ekf", 0.0)).find("--noise-v-mv"), std::string::npos);
  BaselineOptions bad_q = options("ekf", 0.1e-3);
  bad_q.ekf.q_r_ohm_m2_per_sqrt_s = -1.0;
  EXPECT_NE(message(d, bad_q).find("--ekf-q-r"), std::string::npos);
  d.t_s[20] += 0.1;  // a gap: not the fixed tick
  const std::string gap = message(d, options("batch", 0.1e-3));
  EXPECT_NE(gap.find("synthetic"), std::string::npos);
  EXPECT_NE(gap.find("t_s"), std::string::npos);
}

}  // namespace
}  // namespace bms::baselines
