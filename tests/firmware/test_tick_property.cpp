// Property test of the whole tick (estimator safety): over random and worst-case
// measurement sequences, with every beyond-paper feature on, no NaN leaves the tick, the film
// estimate stays inside its configured bounds, theta stays finite and the saved image always
// restores.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <limits>
#include <random>

#include "bms/fw/estimation/bms_core.hpp"

namespace {

using Model = bms::fw::ReducedCell<double>;
using Core = bms::fw::BmsCore<double, Model, 1, 0>;

Core::Config all_features() {
  Core::Config c;
  c.markov_from_model = true;
  c.resync_at_cv_end = true;
  c.nominal_inventory_mol = Model::inventory_of(0.8408, 0.1592);
  c.rcsi_warmup_s = 2.0;
  c.calibrate_bias = true;
  c.average_estimate = true;
  c.nominal_growth_ohm_m2_per_a_m3_s = Model::nominal_film_growth_ohm_m2_per_a_m3_s();
  c.estimator.p0_u = 1e-2;  // far larger than the paper's: a loop that can run away
  c.estimator.p0_y0 = 1e-2;
  return c;
}

// Segments of plausible cycling (CC/CV in both directions, rest) interleaved with garbage.
double pick_voltage(std::mt19937& rng, double nominal) {
  std::uniform_int_distribution<int> kind(0, 19);
  switch (kind(rng)) {
    case 0: return std::numeric_limits<double>::quiet_NaN();
    case 1: return std::numeric_limits<double>::infinity();
    case 2: return -1.0;
    case 3: return 7.0;
    case 4: return std::uniform_real_distribution<double>(0.0, 5.0)(rng);
    default: return nominal;
  }
}

struct Coverage {
  long active = 0;
  unsigned resyncs = 0;
  int calibrated = 0;
};

void run(unsigned seed, int ticks, Coverage& cov) {
  std::mt19937 rng(seed);
  Model model;
  model.init_default();
  const Core::Config cfg = all_features();
  Core core(cfg, model);
  std::uniform_int_distribution<int> seg_len(1, 400);
  std::uniform_int_distribution<int> seg_kind(0, 6);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int left = 0, kind = 0;
  for (int k = 0; k < ticks; ++k) {
    if (left-- <= 0) {
      left = seg_len(rng);
      kind = seg_kind(rng);
    }
    double v = 3.3, i = 0.0;
    bool present = true;
    switch (kind) {
      case 0: v = 3.25 + 0.05 * unit(rng); i = 2.5; break;    // CC discharge
      case 1: v = 2.0; i = 0.1 + 2.4 * unit(rng); break;       // CV discharge
      case 2: v = 3.35 + 0.05 * unit(rng); i = -2.5; break;   // CC charge
      case 3: v = 3.6; i = -(0.05 + 2.4 * unit(rng)); break;  // CV charge
      case 4: v = 3.3; i = 0.0; break;                        // rest
      case 5: v = 5.0 * unit(rng); i = 40.0 * unit(rng) - 20.0; break;  // anything plausible-looking
      default: present = unit(rng) < 0.5; break;              // a bus going away
    }
    v = pick_voltage(rng, v);
    const auto out = core.tick({v, i, present});
    cov.active += out.rcsi_active;
    ASSERT_TRUE(std::isfinite(out.r_film_est_ohm_m2)) << "seed " << seed << " tick " << k;
    ASSERT_GE(out.r_film_est_ohm_m2, cfg.estimator.r_film_min_ohm_m2);
    ASSERT_LE(out.r_film_est_ohm_m2, cfg.estimator.r_film_max_ohm_m2);
    ASSERT_TRUE(std::isfinite(out.z_v));
    ASSERT_TRUE(std::isfinite(out.theta[0]) && std::isfinite(out.theta[1]));
    ASSERT_TRUE(std::isfinite(out.li_loss_ah));
    if (k % 997 == 0) {
      Model m2;
      Core other(cfg, m2);
      ASSERT_TRUE(other.restore(core.save())) << "seed " << seed << " tick " << k;
    }
  }
  cov.resyncs += core.resync_count();
  cov.calibrated += core.bias_calibrated();
}

TEST(TickProperty, RandomAndWorstCaseSequencesKeepEveryOutputFiniteAndBounded) {
  Coverage cov;
  for (unsigned seed = 1; seed <= 6; ++seed) run(seed, 20000, cov);
  // The sequences reach the code under test: RCSI learned, the observer ran, a bias was set.
  EXPECT_GT(cov.active, 1000);
  EXPECT_GT(cov.resyncs, 0u);
  EXPECT_GT(cov.calibrated, 0);
  std::printf("ticks with RCSI learning %ld, resyncs %u, calibrated runs %d of 6\n", cov.active, cov.resyncs,
              cov.calibrated);
}

}  // namespace
