// What the film path does when the current sensor's offset in use changes (BmsCore step 7): the
// identifier forgets what it learned on the old current, values and covariance, and starts again
// from its prior, keeping the nominal law's growth integral G; the path reports the identifier it
// had until the restarted one settles, as at a relinearisation.
#include <gtest/gtest.h>

#include <cmath>

#include "bms/fw/estimation/film_growth_identifier.hpp"
#include "bms/fw/estimation/identifier_film_path.hpp"

namespace {

using Identifier = bms::fw::FilmGrowthIdentifier<double>;
using Path = bms::fw::IdentifierFilmPath<double>;

Identifier::Config config() {
  Identifier::Config c;
  c.r_film_nominal_ohm_m2 = 3.4e-3;
  c.growth_nominal_ohm_m2_per_a_m3_s = 1e-12;
  return c;
}

// An identifier that has learned a charge of data: a film 8 % above the nominal and an inventory
// 0.3 % low, after some growth.
Identifier learned() {
  Identifier id(config());
  for (int k = 0; k < 1000; ++k) id.propagate(-2e3, 0.2);
  id.begin_charge();
  for (int k = 0; k < 2000; ++k) {
    const double s_v = 0.3 + 0.5 * k / 2000.0;  // S's shape over a charge differs from H's
    const double z_v = 0.02 * (3.4e-3 - 3.672e-3) + s_v * (0.0 - (-0.003));
    id.learn(3.4e-3, z_v, 0.02, s_v, 0.0, 0.0);
  }
  return id;
}

TEST(FilmIdentifierRestart, RestartReturnsToThePriorAndKeepsTheGrowthIntegral) {
  Identifier id = learned();
  const Identifier fresh(config());
  ASSERT_GT(id.growth_ohm_m2(), 0.0);
  ASSERT_NEAR(id.inventory_deviation(), -0.003, 2e-4) << "the data were learned";
  const double g_before = id.growth_ohm_m2();

  Identifier relinearised = id;
  relinearised.relinearise();
  EXPECT_EQ(relinearised.theta(), id.theta()) << "a relinearisation keeps the values as the prior mean";

  id.restart_from_prior();
  EXPECT_EQ(id.theta(), fresh.theta()) << "the values learned on the old current are forgotten";
  EXPECT_EQ(id.p(), fresh.p()) << "and their covariance";
  EXPECT_EQ(id.growth_ohm_m2(), g_before) << "G is the cell's history, not learned";
  EXPECT_EQ(id.inventory_deviation(), 0.0);
}

TEST(FilmIdentifierRestart, PathForgetsAndHoldsWhatItReported) {
  Path::Config pc;
  pc.identifier = config();
  Path path(pc, 0.2);
  const Identifier id = learned();
  ASSERT_TRUE(path.restore(Path::State{id.save()}));
  ASSERT_FALSE(path.holding());
  const double film = path.r_film_ohm_m2();
  ASSERT_NEAR(film, id.film_ohm_m2(), 1e-15);

  path.forget();
  EXPECT_TRUE(path.holding());
  EXPECT_EQ(path.r_film_ohm_m2(), film) << "held until the restarted identifier settles";
  EXPECT_EQ(path.identifier().theta(), Identifier(config()).theta());
  EXPECT_EQ(path.inventory_deviation(), 0.0) << "the re-synchronisation places the model at the prior's inventory";

  Path::Config no_hold = pc;
  no_hold.hold_until_settled = false;
  Path unheld(no_hold, 0.2);
  ASSERT_TRUE(unheld.restore(Path::State{id.save()}));
  unheld.forget();
  EXPECT_FALSE(unheld.holding());
  EXPECT_DOUBLE_EQ(unheld.r_film_ohm_m2(), 3.4e-3 + id.growth_ohm_m2()) << "the prior's film, grown by G";
}

// A relinearised (restarted) fit is reported only once it has learned a whole CC charge: the end
// of a charge it did not learn in does not release the hold (measured: under a current gain the
// restarted fit is 8-9 % off for most of its first charge; docs/results/envelope.md).
TEST(FilmIdentifierRestart, RestartIsHeldUntilTheRestartedFitLearnedACharge) {
  Path::Config pc;
  pc.identifier = config();
  Path path(pc, 0.2);
  const Identifier id = learned();
  ASSERT_TRUE(path.restore(Path::State{id.save()}));
  const double film = path.r_film_ohm_m2();

  path.relinearise();
  EXPECT_TRUE(path.holding());
  path.charge_ended();
  EXPECT_TRUE(path.holding()) << "no charge learned since the restart";
  EXPECT_EQ(path.r_film_ohm_m2(), film);
  path.forget();  // a second restart while held keeps what was reported before the first
  EXPECT_TRUE(path.holding());
  EXPECT_EQ(path.r_film_ohm_m2(), film);
}

}  // namespace

// The regression's a-priori innovation (the consistency check on the fusion,
// IdentifierFilmPath::Config::innovation_rejects): what the fit leaves of a tick's residual. On
// the data it was fitted to it is near 0 even though the model's own residual is not (the model
// sits at the nominal inventory, the fit at -0.3 %); a residual 2 mV above them reads as -2 mV.
TEST(FilmIdentifierRestart, InnovationIsWhatTheFitLeavesOfTheResidual) {
  const Identifier id = learned();
  const double s_v = 0.55, h = 0.02;
  const double z_v = h * (3.4e-3 - 3.672e-3) + s_v * 0.003;
  ASSERT_GT(std::fabs(z_v), 1e-3) << "the model's residual is not small";
  EXPECT_NEAR(id.innovation_v(3.4e-3, z_v, h, s_v, 0.0, 0.0), 0.0, 2e-5);
  EXPECT_NEAR(id.innovation_v(3.4e-3, z_v + 2e-3, h, s_v, 0.0, 0.0), -2e-3, 2e-5);
  EXPECT_NEAR(id.innovation_v(3.4e-3, z_v + 2e-3, h, s_v, 0.0, 2e-3), 0.0, 2e-5) << "the bias is removed";
  EXPECT_TRUE(std::isnan(id.innovation_v(3.4e-3, z_v, 0.0, s_v, 0.0, 0.0))) << "no H: learn() rejects it";
}
