// The truth model driven by a measured current (run_current_profile), which the diagnosis
// and `simulate --protocol csv:` use: a smoothly decaying current (a CV phase) must be
// followed closely, not as a staircase, and a jump must stay a jump. The staircase of the
// former 1 %-of-maximum segmentation was the 0.40 mV floor of docs/results/diagnosis.md.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <vector>

#include "cell/paper_cell.hpp"
#include "sim/cycler.hpp"

namespace {

bms::SimulationConfig coarse_paper() {
  bms::SimulationConfig cfg;
  cfg.cell = bms::make_paper_cell();
  cfg.mesh = bms::DfnMesh{6, 6, 6, 6};
  cfg.ic = bms::default_initial_conditions(cfg.cell);
  return cfg;
}

TEST(ProfileDrive, FollowsADecayingCurrentAndKeepsAJump) {
  // 20 s at rest, a jump to 2.5 A for 100 s, then a CV-like decay 2.5 exp(-t / 150 s) for 600 s.
  std::vector<double> t, i;
  for (int k = 0; k <= 720; ++k) {
    t.push_back(k);
    i.push_back(k < 20 ? 0.0 : k < 120 ? 2.5 : 2.5 * std::exp(-(k - 120) / 150.0));
  }
  const auto r = bms::run_current_profile(coarse_paper(), t, i, 1.0, 5.0);
  ASSERT_EQ(r.samples.size(), t.size()) << r.note;
  double worst = 0.0, charge_data = 0.0, charge_model = 0.0;
  for (std::size_t k = 0; k < t.size(); ++k) {
    worst = std::max(worst, std::abs(r.samples[k].current_a - i[k]));
    if (k > 0) {
      charge_data += 0.5 * (i[k] + i[k - 1]);
      charge_model += 0.5 * (r.samples[k].current_a + r.samples[k - 1].current_a);
    }
  }
  // 0.02 % of the largest current (0.5 mA) plus round-off; a 1 % staircase is 25 mA off.
  EXPECT_LT(worst, 0.6e-3) << "largest difference between the driving and the measured current";
  std::printf("largest current difference %.3f mA, charge %.4f vs %.4f A s\n", 1e3 * worst, charge_model, charge_data);
  // Every piece stays within 0.5 mA of the samples: at most 0.36 A s over 720 s (of 619 A s).
  EXPECT_NEAR(charge_model, charge_data, 0.15);
  // The jump: the sample after it carries the full current, the one before none.
  EXPECT_NEAR(r.samples[19].current_a, 0.0, 1e-5);
  EXPECT_NEAR(r.samples[20].current_a, 2.5, 1e-5);  // the solver's tolerance
}

TEST(ProfileDrive, JitterDoesNotBecomeKinksOrSteps) {
  // A constant 1 A read through a 0.65 mA ADC that toggles every few samples (as the
  // About:Energy files): the driving current stays within the jitter of the data.
  std::vector<double> t, i;
  for (int k = 0; k <= 600; ++k) {
    t.push_back(k);
    i.push_back(1.0 + ((k / 3) % 2 == 0 ? 0.0 : 0.00065));
  }
  const auto r = bms::run_current_profile(coarse_paper(), t, i, 1.0, 5.0);
  ASSERT_EQ(r.samples.size(), t.size()) << r.note;
  for (std::size_t k = 0; k < t.size(); ++k) EXPECT_NEAR(r.samples[k].current_a, i[k], 1.4e-3) << k;
  // No toggle is taken for a step (each would re-initialise the integrator): start + switch only.
  EXPECT_LE(r.stats.reinits, 2);
}

}  // namespace
