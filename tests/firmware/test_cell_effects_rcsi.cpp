// RCSI with an effect the main model does not declare, in seconds:
// the plant is the reduced model plus a contact resistance or a current-sensor offset, the
// estimator runs BmsCore on the plain model ("before") and on the model augmented with the
// effect ("after"). In CC charge a contact resistance adds R_c |I| to the measured voltage,
// which RCSI can only read as film (dV/dR_film = +0.88 V per ohm m2 at 2.5 A): the plain
// model must over-estimate the film, the augmented one must not. The long version on the
// truth DFN is in docs/results/diagnosis.md.
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>

#include "bms/fw/estimation/bms_core.hpp"
#include "bms/fw/model/cell_effects.hpp"
#include "bms/fw/model/paper_cell.hpp"

namespace {

using Plain = bms::fw::ReducedCell<double>;
using Augmented = bms::fw::EffectsModel<Plain, bms::fw::kAllCellEffects>;
constexpr double kFilm = bms::fw::paper::kInitialFilm_ohm_m2;
constexpr double kDt = 0.2;

bms::fw::EffectParameters<double> effect(double r_c_ohm, double offset_a) {
  bms::fw::EffectParameters<double> p;
  p.nominal_capacity_ah = 2.3;
  p.contact_resistance_ohm = r_c_ohm;
  p.current_offset_a = offset_a;
  return p;
}

template <class Model>
typename bms::fw::BmsCore<double, Model>::Config config() {
  typename bms::fw::BmsCore<double, Model>::Config cfg;
  cfg.markov_from_model = true;  // H = dV/dR_film: the loop then settles within one charge
  return cfg;
}

// Relative film error (estimate - truth) / truth at the end of a 2000 s discharge and an
// 800 s CC charge, for a plant with plant_effect and the given main model (which starts from
// the same state as the plant's cell).
template <class Model>
double film_error(const bms::fw::EffectParameters<double>& plant_effect, Model& model) {
  Plain plant_cell;
  plant_cell.init_default();
  Augmented plant(plant_cell, plant_effect);
  bms::fw::BmsCore<double, Model> core(config<Model>(), model);
  auto tick = [&](double cell_current_a) {
    // The sensor reads the cell current plus its offset.
    const double meas_i = cell_current_a + plant_effect.current_offset_a;
    const auto r = plant.step_current(meas_i, kFilm, kDt);
    return core.tick({r.voltage_v, meas_i, true});
  };
  for (int k = 0; k < 10000; ++k) tick(2.5);
  bms::fw::TickOutput<double, 1> out{};
  for (int k = 0; k < 4000; ++k) out = tick(-2.5);
  EXPECT_EQ(out.mode, bms::fw::Mode::cc_charge);
  return (core.r_film_ohm_m2() - kFilm) / kFilm;
}

struct BeforeAfter {
  double before, after;
};

BeforeAfter run_both(const bms::fw::EffectParameters<double>& plant_effect) {
  Plain plain;
  plain.init_default();
  Plain inner;
  inner.init_default();
  Augmented augmented(inner, plant_effect);  // the diagnosed effect, exactly
  const BeforeAfter e{film_error(plant_effect, plain), film_error(plant_effect, augmented)};
  std::printf("film error at the end of the charge: plain model %+.2f %%, augmented %+.3f %%\n", 100.0 * e.before,
              100.0 * e.after);
  return e;
}

TEST(CellEffectsRcsi, ContactResistanceBiasesThePlainModelAndTheAugmentedModelRemovesIt) {
  const BeforeAfter e = run_both(effect(1e-3, 0.0));
  // 1 mohm x 2.5 A = 2.5 mV, / 0.88 V per ohm m2 = 2.8e-3 ohm m2: +84 % of the film.
  EXPECT_GT(e.before, 0.3) << "plain model: " << e.before;
  EXPECT_LT(std::abs(e.after), 0.1 * e.before) << "augmented: " << e.after << ", plain: " << e.before;
}

TEST(CellEffectsRcsi, CurrentOffsetBiasesThePlainModelAndTheAugmentedModelRemovesIt) {
  const BeforeAfter e = run_both(effect(0.0, 0.01));
  EXPECT_GT(std::abs(e.before), 0.02) << "plain model: " << e.before;
  EXPECT_LT(std::abs(e.after), 0.25 * std::abs(e.before)) << "augmented: " << e.after << ", plain: " << e.before;
}

}  // namespace
