// One configuration path: `bmssim estimate` runs the firmware's own configuration for each
// profile (make_config over the nominal cell, field for field), and an override a profile does
// not use is refused, for every override.
#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <functional>
#include <type_traits>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "bms/fw/config/cell_choice.hpp"
#include "bms/fw/config/make_config.hpp"
#include "estimation/estimate_run.hpp"
#include "sim/cell_catalog.hpp"

namespace {

namespace fw = bms::fw;
using Model = fw::ReducedCell<double>;
using RcsiCore = fw::CoreFor<fw::Profile::paper, double, Model>;
using IdentifierCore = fw::CoreFor<fw::Profile::best, double, Model>;
using Field = std::pair<std::string, double>;

// Each film path's own Config fields, named.
void add_path_fields(const fw::RcsiFilmPath<double>::Config& c, std::vector<Field>& f) {
  const std::vector<Field> g = {
      {"estimator.markov_v_per_ohm_m2", c.estimator.markov_v_per_ohm_m2},
      {"estimator.eta", c.estimator.eta},
      {"estimator.lambda", c.estimator.lambda},
      {"estimator.p0_u", c.estimator.p0_u},
      {"estimator.p0_y0", c.estimator.p0_y0},
      {"estimator.p_trace_cap_factor", c.estimator.p_trace_cap_factor},
      {"estimator.r_film_init_ohm_m2", c.estimator.r_film_init_ohm_m2},
      {"estimator.j_side_init_a_m3", c.estimator.j_side_init_a_m3},
      {"estimator.r_film_min_ohm_m2", c.estimator.r_film_min_ohm_m2},
      {"estimator.r_film_max_ohm_m2", c.estimator.r_film_max_ohm_m2},
      {"markov_from_model", c.markov_from_model},
      {"calibrate_bias", c.calibrate_bias},
      {"reference_after_resyncs", c.reference_after_resyncs},
      {"average_estimate", c.average_estimate},
      {"nominal_growth_ohm_m2_per_a_m3_s", c.nominal_growth_ohm_m2_per_a_m3_s}};
  f.insert(f.end(), g.begin(), g.end());
  for (int k = 0; k < 2; ++k) f.emplace_back("estimator.theta0(" + std::to_string(k) + ")", c.estimator.theta0(k));
}
void add_path_fields(const fw::IdentifierFilmPath<double>::Config& c, std::vector<Field>& f) {
  const std::vector<Field> g = {
      {"identifier.r_film_nominal_ohm_m2", c.identifier.r_film_nominal_ohm_m2},
      {"identifier.growth_nominal_ohm_m2_per_a_m3_s", c.identifier.growth_nominal_ohm_m2_per_a_m3_s},
      {"identifier.prior_r0_ohm_m2", c.identifier.prior_r0_ohm_m2},
      {"identifier.prior_gain", c.identifier.prior_gain},
      {"identifier.prior_inventory", c.identifier.prior_inventory},
      {"identifier.sigma_u_ohm_m2", c.identifier.sigma_u_ohm_m2},
      {"identifier.r_film_min_ohm_m2", c.identifier.r_film_min_ohm_m2},
      {"identifier.r_film_max_ohm_m2", c.identifier.r_film_max_ohm_m2},
      {"identifier.inventory_limit", c.identifier.inventory_limit},
      {"identifier.learn_inventory", c.identifier.learn_inventory},
      {"identifier.film_model_sd_rel", c.identifier.film_model_sd_rel},
      {"identifier.inventory_model_sd", c.identifier.inventory_model_sd},
      {"model_bias_ohm", c.model_bias_ohm},
      {"model_bias_table.nominal.x_trusted_last", c.model_bias_table.nominal().x_trusted_last},
      {"model_bias_table.nu_step", c.model_bias_table.nu_step},
      {"relinearise_inventory", c.relinearise_inventory},
      {"innovation_time_constant_s", c.innovation_time_constant_s},
      {"innovation_sd_v", c.innovation_sd_v},
      {"innovation_gate", c.innovation_gate},
      {"innovation_rejects", c.innovation_rejects},
      {"hold_through_restarted_charge", c.hold_through_restarted_charge},
      {"temperature_sd_k", c.temperature_sd_k},
      {"spread.anode_i0_rel", c.spread.anode_i0_rel},
      {"spread.cathode_i0_rel", c.spread.cathode_i0_rel},
      {"spread.transport_rel", c.spread.transport_rel},
      {"spread.area_rel", c.spread.area_rel},
      {"voltage_offset_sd_v", c.voltage_offset_sd_v},
      {"current_gain_sd", c.current_gain_sd}};
  f.insert(f.end(), g.begin(), g.end());
}

// Every field of BmsCore::Config, named, so a difference says which.
template <class Config>
std::vector<Field> fields(const Config& c) {
  std::vector<Field> f = {
      {"detector.rest_current_a", c.detector.rest_current_a},
      {"detector.cc_tolerance_a", c.detector.cc_tolerance_a},
      {"detector.cv_band_v", c.detector.cv_band_v},
      {"detector.v_max", c.detector.v_max},
      {"detector.v_min", c.detector.v_min},
      {"detector.debounce_ticks", c.detector.debounce_ticks},
      {"dt_s", c.dt_s},
      {"voltage_min_v", c.voltage_min_v},
      {"voltage_max_v", c.voltage_max_v},
      {"current_limit_a", c.current_limit_a},
      {"current_step_limit_a", c.current_step_limit_a},
      {"stale_limit_ticks", c.stale_limit_ticks},
      {"catch_up_max_ticks", c.catch_up_max_ticks},
      {"catch_up_max_steps", c.catch_up_max_steps},
      {"catch_up_max_voltage_steps", c.catch_up_max_voltage_steps},
      {"resync_at_cv_end", c.resync_at_cv_end},
      {"resync_at_start", c.resync_at_start},
      {"resync_current_a", c.resync_current_a},
      {"resync_window_ticks", c.resync_window_ticks},
      {"nominal_inventory_mol", c.nominal_inventory_mol},
      {"rcsi_warmup_s", c.rcsi_warmup_s},
      {"learning", c.learning},
      {"voltage_offset", c.voltage_offset}};
  add_path_fields(c.film_path, f);
  return f;
}

// f(CoreTag<Core>{}) with the core the profile names (as bmssim estimate and bms-firmware pick it).
template <class F>
void with_core(fw::Profile p, F&& f) {
  fw::with_core_for<double, Model, 1, 0>(p, std::forward<F>(f));
}

const fw::Profile kProfiles[] = {fw::Profile::paper, fw::Profile::best, fw::Profile::nominal_growth};

// Each profile builds the film path it names: at build time (CoreFor, the board images) and at
// start (with_core_for, the host and bms-firmware); make_config refuses a core of the other path.
static_assert(std::is_same<RcsiCore::FilmPath, fw::RcsiFilmPath<double, 1, 0>>::value, "paper runs RCSI");
static_assert(std::is_same<fw::CoreFor<fw::Profile::nominal_growth, double, Model>::FilmPath,
                           fw::RcsiFilmPath<double, 1, 0>>::value,
              "nominal-growth runs RCSI");
static_assert(std::is_same<IdentifierCore::FilmPath, fw::IdentifierFilmPath<double>>::value, "best identifies");
static_assert(std::is_same<fw::CoreFor<fw::Profile::best, float, fw::ReducedCell<float>>::FilmPath,
                           fw::IdentifierFilmPath<float>>::value,
              "the M4F image's best identifies in float");
TEST(FilmPath, EachProfileBuildsThePathItNames) {
  EXPECT_EQ(fw::film_path_of(fw::Profile::paper), fw::FilmPathKind::rcsi);
  EXPECT_EQ(fw::film_path_of(fw::Profile::nominal_growth), fw::FilmPathKind::rcsi);
  EXPECT_EQ(fw::film_path_of(fw::Profile::best), fw::FilmPathKind::identifier);
  for (fw::Profile p : kProfiles) {
    const fw::FilmPathKind started = fw::with_core_for<double, Model, 1, 0>(
        p, [](auto core) { return decltype(core)::type::FilmPath::kKind; });
    EXPECT_EQ(started, fw::film_path_of(p)) << fw::profile_name(p);
    with_core(p, [&](auto core) {
      using Core = typename decltype(core)::type;
      EXPECT_TRUE(fw::runs_path_of<Core>(p));
      // The other path's core is refused, naming the profile's option.
      using Other = std::conditional_t<std::is_same<Core, RcsiCore>::value, IdentifierCore, RcsiCore>;
      typename Other::Config cfg{};
      const fw::Refusal r = fw::make_config<Other>(fw::paper_nominal_cell<double>(), p, fw::Overrides{}, cfg);
      ASSERT_NE(r.option, nullptr) << fw::profile_name(p);
      EXPECT_STREQ(r.option, "settings");
    });
  }
}

// The identifier's path takes the model's probes, RCSI's never: the tick runs what its type says.
TEST(FilmPath, TheTickRunsThePathsSteps) {
  for (fw::Profile p : kProfiles) {
    with_core(p, [&](auto core_tag) {
      using Core = typename decltype(core_tag)::type;
      Model m, plant;
      m.init_default();
      plant.init_default();
      Core core(fw::paper_cell_config<Core>(p), m);
      typename Core::Output out{};
      for (int k = 0; k < 13000; ++k) {  // a CC discharge, then a CC charge past the warm-ups
        const double current_a = k < 7500 ? 2.5 : -2.5;
        const auto y = plant.step_current(current_a, fw::PaperCellTraits::kInitialFilmOhmM2, 0.2);
        out = core.tick({y.voltage_v, current_a, true});
      }
      ASSERT_EQ(out.mode, fw::Mode::cc_charge) << fw::profile_name(p);
      const bool identifies = fw::film_path_of(p) == fw::FilmPathKind::identifier;
      EXPECT_EQ(std::isnan(out.r_film_sd_ohm_m2), !identifies) << fw::profile_name(p);
      EXPECT_EQ(out.inventory_sensitivity_v != 0.0, identifies) << fw::profile_name(p);
    });
  }
}

// bmssim estimate on the paper cell's reduced model, each profile without options, runs exactly
// the configuration bms-firmware and the board images run (bit for bit).
TEST(EstimateConfig, EqualsTheFirmwaresForEachProfile) {
  const bms::CellParameters cell = bms::load_cell("paper");
  for (fw::Profile p : kProfiles) {
    with_core(p, [&](auto core) {
      using Core = typename decltype(core)::type;
      bms::EstimateOptions o;
      o.profile = p;
      typename Core::Config estimate{};
      const fw::Refusal r = bms::estimate_config<Core>(cell, o, 0.2, estimate);
      ASSERT_EQ(r.option, nullptr) << fw::profile_name(p);
      const auto a = fields(estimate), b = fields(fw::paper_cell_config<Core>(p));
      ASSERT_EQ(a.size(), b.size());
      for (std::size_t i = 0; i < a.size(); ++i)
        EXPECT_EQ(a[i].second, b[i].second) << fw::profile_name(p) << ": " << a[i].first;
    });
  }
}

// The profiles differ where they say they do (the comparison above is not vacuous).
TEST(EstimateConfig, ProfilesDiffer) {
  const auto paper = fw::paper_cell_config<RcsiCore>(fw::Profile::paper);
  const auto best = fw::paper_cell_config<IdentifierCore>(fw::Profile::best);
  const auto growth = fw::paper_cell_config<RcsiCore>(fw::Profile::nominal_growth);
  EXPECT_FALSE(paper.film_path.markov_from_model || paper.resync_at_cv_end);
  EXPECT_EQ(paper.film_path.estimator.markov_v_per_ohm_m2, fw::kPaperMarkovVPerOhmM2);
  EXPECT_EQ(paper.film_path.estimator.p0_u, fw::kPaperCovarianceP0);
  EXPECT_TRUE(best.resync_at_cv_end && best.rcsi_warmup_s == 900.0);
  EXPECT_GT(best.film_path.model_bias_ohm, 0.0);
  EXPECT_GT(best.film_path.identifier.growth_nominal_ohm_m2_per_a_m3_s, 0.0);
  EXPECT_TRUE(growth.film_path.calibrate_bias && growth.film_path.average_estimate &&
              growth.film_path.nominal_growth_ohm_m2_per_a_m3_s > 0.0);
  EXPECT_EQ(growth.rcsi_warmup_s, 600.0);
  EXPECT_GT(paper.voltage_min_v, 0.0);  // the cell's window, not 0-5 V
}

// Each override alone, on each profile: refused exactly where the profile does not use it.
struct OverrideCase {
  const char* option;
  std::function<void(fw::Overrides&)> set;
};
const std::vector<OverrideCase>& override_cases() {
  static const std::vector<OverrideCase> c = {
      {"nc", [](fw::Overrides& o) { o.nc = 1; }},
      {"h", [](fw::Overrides& o) { o.h_v_per_ohm_m2 = 0.02; }},
      {"h-from-model", [](fw::Overrides& o) { o.h_from_model = true; }},
      {"p0", [](fw::Overrides& o) { o.p0 = 1e-3; }},
      {"p0-y0", [](fw::Overrides& o) { o.p0_y0 = 1e-3; }},
      {"lambda", [](fw::Overrides& o) { o.lambda = 0.999; }},
      {"eta", [](fw::Overrides& o) { o.eta = 1.0; }},
      {"theta0", [](fw::Overrides& o) { o.theta0 = fw::Theta0{{0.0, 0.0}, 2}; }},
      {"r-film-init", [](fw::Overrides& o) { o.r_film_init_ohm_m2 = 4e-3; }},
      {"calibrate-bias", [](fw::Overrides& o) { o.calibrate_bias = true; }},
      {"reference-after-resyncs", [](fw::Overrides& o) { o.reference_after_resyncs = 2u; }},
      {"average", [](fw::Overrides& o) { o.average_estimate = true; }},
      {"propagate-growth", [](fw::Overrides& o) { o.propagate_growth = true; }},
      {"growth-scale", [](fw::Overrides& o) { o.growth_scale = 2.0; }},
      {"no-learning", [](fw::Overrides& o) { o.learning = false; }},
      {"warmup", [](fw::Overrides& o) { o.warmup_s = 30.0; }},
      {"resync", [](fw::Overrides& o) { o.resync = true; }},
      {"no-start-resync", [](fw::Overrides& o) { o.resync_at_start = false; }},
      {"resync-window", [](fw::Overrides& o) { o.resync_window_ticks = 3u; }},
      {"resync-current", [](fw::Overrides& o) { o.resync_current_a = 0.2; }},
      {"no-inventory", [](fw::Overrides& o) { o.learn_inventory = false; }},
      {"model-bias-ohm", [](fw::Overrides& o) { o.model_bias_ohm = 0.0; }},
      {"relinearise", [](fw::Overrides& o) { o.relinearise_inventory = 1.0; }},
      {"spread-anode-i0", [](fw::Overrides& o) { o.spread_anode_i0_rel = 0.1; }},
      {"spread-cathode-i0", [](fw::Overrides& o) { o.spread_cathode_i0_rel = 0.1; }},
      {"spread-transport", [](fw::Overrides& o) { o.spread_transport_rel = 0.1; }},
      {"spread-area", [](fw::Overrides& o) { o.spread_area_rel = 0.01; }},
      {"voltage-offset-sd-mv", [](fw::Overrides& o) { o.voltage_offset_sd_mv = 0.3; }},
      {"current-gain-sd-pct", [](fw::Overrides& o) { o.current_gain_sd_pct = 0.3; }},
      {"voltage-offset", [](fw::Overrides& o) { o.voltage_offset = true; }},
      {"innovation-reject", [](fw::Overrides& o) { o.innovation_rejects = true; }},
      {"no-trusted-span", [](fw::Overrides& o) { o.trusted_span = false; }},
      {"trusted-span-end", [](fw::Overrides& o) { o.trusted_span_end = 0.7; }},
      {"innovation-gate", [](fw::Overrides& o) { o.innovation_gate = 3.0; }},
      {"hold-restarted-charge", [](fw::Overrides& o) { o.hold_restarted_charge = true; }},
  };
  return c;
}

std::set<std::string> expected_unused(fw::Profile p) {
  switch (p) {
    case fw::Profile::paper:  // no observer, no bias calibration, no propagation, H given
      return {"reference-after-resyncs", "growth-scale", "no-start-resync", "resync-window", "resync-current",
              "no-inventory", "model-bias-ohm", "relinearise", "spread-anode-i0", "spread-cathode-i0",
              "spread-transport", "spread-area", "voltage-offset-sd-mv", "current-gain-sd-pct", "voltage-offset",
              "innovation-reject", "no-trusted-span", "trusted-span-end", "innovation-gate", "hold-restarted-charge"};
    case fw::Profile::best:  // the eleven, and what only RCSI reads
      return {"nc", "h", "p0", "p0-y0", "lambda", "eta", "theta0", "r-film-init", "calibrate-bias",
              "reference-after-resyncs", "average", "propagate-growth", "growth-scale"};
    case fw::Profile::nominal_growth:  // H from the model; no identifier
      return {"h", "no-inventory", "model-bias-ohm", "relinearise", "spread-anode-i0", "spread-cathode-i0",
              "spread-transport", "spread-area", "voltage-offset-sd-mv", "current-gain-sd-pct", "voltage-offset",
              "innovation-reject", "no-trusted-span", "trusted-span-end", "innovation-gate", "hold-restarted-charge"};
  }
  return {};
}

TEST(EstimateConfig, EveryUnusedOverrideIsRefusedAndNoUsedOne) {
  for (fw::Profile p : kProfiles) {
    const std::set<std::string> unused = expected_unused(p);
    for (const auto& c : override_cases()) {
      fw::Overrides o;
      c.set(o);
      with_core(p, [&](auto core) {
        using Core = typename decltype(core)::type;
        typename Core::Config cfg{};
        const fw::Refusal r = fw::make_config<Core>(fw::paper_nominal_cell<double>(), p, o, cfg);
        if (unused.count(c.option) != 0) {
          ASSERT_NE(r.option, nullptr) << fw::profile_name(p) << " --" << c.option << " was accepted";
          EXPECT_STREQ(r.option, c.option) << fw::profile_name(p);
          EXPECT_GT(std::strlen(r.reason), 10u);
        } else {
          EXPECT_EQ(r.option, nullptr) << fw::profile_name(p) << " --" << c.option << " refused: " << r.reason;
        }
      });
    }
  }
}

// An accepted override changes the configuration (it does something).
TEST(EstimateConfig, AcceptedOverridesChangeTheConfiguration) {
  for (fw::Profile p : kProfiles) {
    const std::set<std::string> unused = expected_unused(p);
    with_core(p, [&](auto core) {
    using Core = typename decltype(core)::type;
    const auto base = fields(fw::paper_cell_config<Core>(p));
    for (const auto& c : override_cases()) {
      if (unused.count(c.option) != 0) continue;
      fw::Overrides o;
      c.set(o);
      typename Core::Config cfg{};
      ASSERT_EQ((fw::make_config<Core>(fw::paper_nominal_cell<double>(), p, o, cfg).option), nullptr);
      const auto got = fields(cfg);
      bool changed = false;
      for (std::size_t i = 0; i < got.size(); ++i) changed = changed || got[i].second != base[i].second;
      // Redundant switches (a flag the profile already has on, n_c = 1) may leave it as it was.
      // The paper cell has no trusted span's end to switch off.
      const bool redundant = (std::string(c.option) == "nc") || (std::string(c.option) == "no-trusted-span") ||
                             (p != fw::Profile::paper && (std::string(c.option) == "h-from-model" ||
                                                          std::string(c.option) == "resync")) ||
                             (p == fw::Profile::nominal_growth &&
                              (std::string(c.option) == "calibrate-bias" || std::string(c.option) == "average" ||
                               std::string(c.option) == "propagate-growth"));
      if (!redundant) {
        EXPECT_TRUE(changed) << fw::profile_name(p) << " --" << c.option << " changed nothing";
      }
    }
    });
  }
}

TEST(EstimateConfig, ProfileNames) {
  fw::Profile p{};
  ASSERT_TRUE(fw::parse_profile("nominal-growth", p));
  EXPECT_EQ(p, fw::Profile::nominal_growth);
  ASSERT_TRUE(fw::parse_profile("beyond-paper", p));  // the older name
  EXPECT_EQ(p, fw::Profile::nominal_growth);
  EXPECT_FALSE(fw::parse_profile("custom", p));
  for (fw::Profile q : kProfiles) {
    ASSERT_TRUE(fw::parse_profile(fw::profile_name(q), p));
    EXPECT_EQ(p, q);
  }
}

}  // namespace

// The phase currents are C-rates of the cell: the paper cell's rest threshold and CV end at its
// own capacity (bit for bit), the same fractions of a smaller cell's, and --resync-current wins;
// the plausibility limits scale up only.
TEST(EstimateConfig, PhaseCurrentsScaleWithTheCellsCapacity) {
  const auto paper = fw::paper_cell_config<IdentifierCore>(fw::Profile::best);
  EXPECT_EQ(paper.detector.rest_current_a, 0.05);
  EXPECT_EQ(paper.resync_current_a, 0.25);
  fw::NominalCell small = fw::paper_nominal_cell<double>();
  small.nominal_capacity_ah = 0.873;  // the LCO template's: its C/20 CV end is 0.044 A
  const auto lco = fw::make_config<IdentifierCore>(small, fw::Profile::best);
  EXPECT_DOUBLE_EQ(lco.detector.rest_current_a, 0.05 * 0.873 / 2.3);
  EXPECT_DOUBLE_EQ(lco.resync_current_a, 0.25 * 0.873 / 2.3);
  EXPECT_LT(lco.detector.rest_current_a, 0.873 / 20.0) << "the CV tail must not read as rest";
  // The plausibility limits never shrink below the paper cell's 20 A, and grow with a larger cell.
  EXPECT_EQ(lco.current_limit_a, paper.current_limit_a);
  EXPECT_EQ(lco.current_step_limit_a, paper.current_step_limit_a);
  fw::NominalCell large = small;
  large.nominal_capacity_ah = 5.0;  // the NMC template's
  const auto nmc = fw::make_config<IdentifierCore>(large, fw::Profile::best);
  EXPECT_DOUBLE_EQ(nmc.current_limit_a, 20.0 * 5.0 / 2.3);
  EXPECT_DOUBLE_EQ(nmc.current_step_limit_a, 20.0 * 5.0 / 2.3);
  small.nominal_capacity_ah = 0.0;  // not given: the paper cell's amperes
  EXPECT_EQ(fw::make_config<IdentifierCore>(small, fw::Profile::best).resync_current_a, 0.25);
  small.nominal_capacity_ah = 0.873;
  fw::Overrides o;
  o.resync_current_a = 0.1;
  IdentifierCore::Config cfg{};
  ASSERT_EQ((fw::make_config<IdentifierCore>(small, fw::Profile::best, o, cfg).option), nullptr);
  EXPECT_EQ(cfg.resync_current_a, 0.1);
  // The cell's record carries it: estimate's nominal cell of the LCO has its capacity.
  bms::EstimateOptions eo;
  eo.profile = fw::Profile::paper;  // a profile without the design-time bias, which needs the DFN
  EXPECT_EQ(bms::estimate_nominal_cell(bms::load_cell("lco"), eo).nominal_capacity_ah, 0.873);
}

// The generated About:Energy configuration carries its bias table at three inventories; the
// firmware's configuration holds them, --no-bias-levels keeps the nominal level alone (the
// ablation), --no-bias-table drops every level's knots and keeps every level's trusted span.
TEST(EstimateConfig, BiasLevelsOverTheInventoryAndTheirAblations) {
  using Choice = fw::GeneratedCell<fw::cells::AboutenergyCellTraits, fw::AboutenergyName>;
  const fw::NominalCell ae = fw::nominal_cell_of<double, Choice>();
  ASSERT_TRUE(ae.model_bias_table.valid());
  EXPECT_EQ(ae.model_bias_table.nu_step, 0.01);
  EXPECT_TRUE(ae.model_bias_table.level[0].on() && ae.model_bias_table.level[2].on());
  const auto full = fw::make_config<IdentifierCore>(ae, fw::Profile::best);
  EXPECT_EQ(full.film_path.model_bias_table.nu_step, 0.01);
  const double x = 0.5;
  EXPECT_NE(full.film_path.model_bias_table.at(x, 0.01), full.film_path.model_bias_table.at(x, 0.0));
  fw::Overrides o;
  o.model_bias_levels = false;
  IdentifierCore::Config cfg{};
  ASSERT_EQ((fw::make_config<IdentifierCore>(ae, fw::Profile::best, o, cfg).option), nullptr);
  EXPECT_EQ(cfg.film_path.model_bias_table.nu_step, 0.0);
  EXPECT_EQ(cfg.film_path.model_bias_table.at(x, 0.01), ae.model_bias_table.nominal().at(x));
  fw::Overrides no_table;
  no_table.model_bias_table = false;
  ASSERT_EQ((fw::make_config<IdentifierCore>(ae, fw::Profile::best, no_table, cfg).option), nullptr);
  EXPECT_FALSE(cfg.film_path.model_bias_table.on());
  EXPECT_EQ(cfg.film_path.model_bias_table.trusted_last(-0.01), ae.model_bias_table.level[0].x_trusted_last);
  EXPECT_EQ(cfg.film_path.model_bias_table.trusted_last(0.0), ae.model_bias_table.nominal().x_trusted_last);
  fw::Overrides paper_levels;
  paper_levels.model_bias_levels = false;
  ASSERT_EQ((fw::make_config<IdentifierCore>(fw::paper_nominal_cell<double>(), fw::Profile::best, paper_levels, cfg).option),
            nullptr);
  EXPECT_FALSE(cfg.film_path.model_bias_table.on()) << "the paper cell has no table at any level";
}
