#pragma once
// The one configuration path. What a BMS knows of its cell (the nominal numbers of the data
// sheet and of the model's design, never the cell in use), an estimator profile and a typed set
// of overrides become BmsCore's Config here, and nowhere else: bms-firmware, the board images,
// `bmssim estimate`, `bmssim hil` (through bms-firmware's --settings), the studies and the
// replays all call make_config.
//
// The profiles, named for what they do:
//   paper          - the paper's RCSI (n_c = 1, eta = 0, P(0) = kPaperCovarianceP0 I,
//                    H = kPaperMarkovVPerOhmM2) in CC charge, film held elsewhere;
//   best           - H from the model, the state observer (re-synchronisation at power-up and at
//                    each CV end over 50 ticks), 900 s warm-up, the current sensor's offset and the
//                    electrode-capacity scale (AreaScale, for the capacity) measured, and the film, its growth gain and
//                    the lithium inventory identified together (FilmGrowthIdentifier) against
//                    the model's design-time bias;
//   nominal-growth - RCSI with H from the model, the observer, 600 s warm-up, the bias
//                    calibrated on a reference charge at the nominal initial film, a charge-
//                    averaged estimate carried between charges by the nominal growth law (it
//                    assumes the law: docs/results/firmware-model.md). `--beyond-paper` names it too.
//
// An override the profile does not use is refused (make_config returns its name): no option is
// silently ignored (the contract's "exits 2 naming it").
//
// Each profile names its film path (film_path_of: best the identifier's, the others RCSI's), and
// the core is built for that path: CoreFor<profile, ...> at build time (the board images),
// with_core_for(profile, f) at start (bms-firmware, bmssim estimate and hil). make_config
// refuses a profile whose path is not the core's.
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <type_traits>

#include "bms/fw/estimation/bms_core.hpp"
#include "bms/fw/estimation/identifier_film_path.hpp"
#include "bms/fw/estimation/rcsi_film_path.hpp"
#include "bms/fw/model/model_bias_table.hpp"
#include "bms/fw/model/reduced_cell.hpp"
#include "bms/fw/model/reduced_model_bias.hpp"

namespace bms::fw {

enum class Profile : std::uint8_t { paper, best, nominal_growth };

inline const char* profile_name(Profile p) {
  switch (p) {
    case Profile::paper: return "paper";
    case Profile::best: return "best";
    case Profile::nominal_growth: return "nominal-growth";
  }
  return "?";
}

/// "paper", "best", "nominal-growth" (or its older name "beyond-paper"); false for anything else.
inline bool parse_profile(const char* text, Profile& out) {
  for (Profile p : {Profile::paper, Profile::best, Profile::nominal_growth}) {
    if (std::strcmp(text, profile_name(p)) == 0) {
      out = p;
      return true;
    }
  }
  if (std::strcmp(text, "beyond-paper") != 0) return false;
  out = Profile::nominal_growth;
  return true;
}

/// The film path a profile runs: best identifies the film with its growth law, the paper and
/// nominal-growth profiles run RCSI.
constexpr FilmPathKind film_path_of(Profile p) {
  return p == Profile::best ? FilmPathKind::identifier : FilmPathKind::rcsi;
}

/// The path type of a kind.
template <FilmPathKind K, class Scalar, int Nc, int D>
struct FilmPathOf {
  using type = RcsiFilmPath<Scalar, Nc, D>;
};
template <class Scalar, int Nc, int D>
struct FilmPathOf<FilmPathKind::identifier, Scalar, Nc, D> {
  using type = IdentifierFilmPath<Scalar>;
};

/// The core a profile runs, chosen at build time (the board images).
template <Profile P, class Scalar = double, class MainModel = ReducedCell<Scalar>, int Nc = 1, int D = 0>
using CoreFor = BmsCore<Scalar, MainModel, Nc, D, typename FilmPathOf<film_path_of(P), Scalar, Nc, D>::type>;

/// A core type handed to with_core_for's function (f(CoreTag<Core>{})).
template <class Core>
struct CoreTag {
  using type = Core;
};

/// The core a profile runs, chosen at start (the host, the Linux firmware): calls
/// f(CoreTag<Core>{}) with the core of the profile's film path and returns what f returns.
template <class Scalar, class MainModel, int Nc, int D, class F>
decltype(auto) with_core_for(Profile p, F&& f) {
  using Rcsi = BmsCore<Scalar, MainModel, Nc, D, RcsiFilmPath<Scalar, Nc, D>>;
  using Identifier = BmsCore<Scalar, MainModel, Nc, D, IdentifierFilmPath<Scalar>>;
  if (film_path_of(p) == FilmPathKind::identifier) return f(CoreTag<Identifier>{});
  return f(CoreTag<Rcsi>{});
}

/// Whether Core runs the film path the profile names.
template <class Core>
constexpr bool runs_path_of(Profile p) {
  return Core::FilmPath::kKind == film_path_of(p);
}

/// The nominal cell as the firmware knows it.
struct NominalCell {
  double inventory_mol{};                     ///< cyclable lithium of the nominal cell
  double initial_film_ohm_m2{};               ///< film resistance at the start of life
  double growth_ohm_m2_per_a_m3_s{};          ///< nominal Ramadass constant per side current
  double model_bias_ohm{};                    ///< the reduced model's design-time film bias
  double lower_voltage_v{};                   ///< the cell's voltage window
  double upper_voltage_v{};
  /// The state-of-charge-dependent part of the design-time bias, added to model_bias_ohm, over
  /// the model's inventory where it has levels (off: the constant alone, as for the paper cell).
  ModelBiasTables<double> model_bias_table{};
  /// The cell's nominal capacity [Ah] (0: not given). The currents that mark a protocol's phases
  /// (rest, the CV end the re-synchronisation and the current offset anchor on) are the paper
  /// cell's amperes scaled by it: a C-rate, so that a smaller cell's CV tail is not read as rest.
  double nominal_capacity_ah{};
};

/// Margin of the measured-voltage plausibility check outside the cell's window: a sensor
/// reading of 0 V (what a NaN becomes on the bus) is rejected, not modelled.
inline constexpr double kVoltagePlausibilityMarginV = 0.5;

/// The paper's cell (reduced_cell.hpp's PaperCellTraits) as the nominal cell.
template <class Scalar>
NominalCell paper_nominal_cell() {
  using Model = ReducedCell<Scalar>;
  using Cell = PaperCellTraits;
  return {static_cast<double>(Model::inventory_of(Scalar(Cell::kNeg.stoich_init), Scalar(Cell::kPos.stoich_init))),
          Cell::kInitialFilmOhmM2,
          static_cast<double>(Model::nominal_film_growth_ohm_m2_per_a_m3_s()),
          kPaperReducedModelBiasOhm,
          Cell::kLowerVoltageV,
          Cell::kUpperVoltageV,
          ModelBiasTables<double>{},
          paper::kNominalCapacity_ah};
}

/// One override: unset keeps the profile's value.
template <class T>
struct Given {
  T value{};
  bool given = false;
  Given& operator=(const T& v) {
    value = v;
    given = true;
    return *this;
  }
  T or_else(const T& profile_value) const { return given ? value : profile_value; }
};

/// RCSI's theta(0) = [M1..Mnc, N1..Nnc]: 2 n_c values, n_c <= 8.
struct Theta0 {
  double values[16];
  int count;
};

/// What a caller may change on a profile, typed. Each field's comment names the option of
/// `bmssim estimate` (and bms-firmware where it has it) that sets it.
struct Overrides {
  // RCSI (paper, nominal-growth): the ARX subsystem model and its RLS.
  Given<int> nc;                       // --nc: BmsCore's Nc (the caller picks the type)
  Given<double> h_v_per_ohm_m2;        // --h: not with H from the model
  Given<bool> h_from_model;            // --h-from-model
  Given<double> p0, p0_y0;             // --p0 (both regressors), --p0-y0 (the side-current ones)
  Given<double> lambda, eta;           // --lambda, --eta
  Given<Theta0> theta0;                // --theta0
  Given<double> r_film_init_ohm_m2;    // --r-film-init
  Given<bool> calibrate_bias;          // --calibrate-bias
  Given<unsigned> reference_after_resyncs;  // --reference-after-resyncs: with the bias calibration and the observer
  Given<bool> average_estimate;        // --average
  Given<bool> propagate_growth;        // --propagate-growth
  Given<double> growth_scale;          // --growth-scale: factor on the nominal law while it propagates
  // Every profile.
  Given<bool> learning;                // --no-learning (false)
  Given<double> warmup_s;              // --warmup
  Given<bool> resync;                  // --resync: the state observer on (or off: a main model without one)
  Given<bool> resync_at_start;         // --no-start-resync (false): with the observer
  Given<unsigned> resync_window_ticks; // --resync-window: with the observer
  Given<double> resync_current_a;      // --resync-current: with the observer
  Given<double> resync_settle_s;       // --resync-settle-s: with the observer
  Given<bool> current_offset;          // --no-current-offset (false): the sensor offset from CV end points
  Given<bool> area_scale;              // --no-area-scale (false): the electrode-capacity scale from CV-end pins
  Given<bool> area_scale_model_sees;   // --area-scale-in-model (true): the model runs on I / a too
  // best: the FilmGrowthIdentifier.
  Given<bool> learn_inventory;         // --no-inventory (false)
  Given<double> model_bias_ohm;        // --model-bias-ohm
  Given<bool> model_bias_table;        // --no-bias-table (false): the constant bias alone
  Given<bool> model_bias_levels;       // --no-bias-levels (false): the nominal inventory's table alone
  Given<bool> bias_table_any_start;    // --bias-table-any-start (true): the table for charges begun anywhere
  Given<bool> charge_coverage;         // --no-charge-coverage (false): learn in charges the calibration does not cover
  Given<bool> trusted_span;            // --no-trusted-span (false): learn past the calibration's trusted span
  Given<double> trusted_span_end;      // --trusted-span-end X: the span's end (mean anode stoichiometry)
  Given<double> relinearise_inventory; // --relinearise
  Given<bool> hold_until_settled;      // --no-hold (false)
  Given<bool> hold_restarted_charge;   // --hold-restarted-charge (true)
  Given<bool> innovation_rejects;      // --innovation-reject on|off
  Given<double> innovation_gate;       // --innovation-gate (in innovation_sd_v units)
  Given<double> misfit_stop_s;         // --misfit-stop-s (0: a charge's fusion is never stopped)
  Given<double> inventory_sd;          // --inventory-sd (0: no plausibility test of the fitted inventory)
  // best: the cell's stated parameter spread (relative 1-sigma, StatedSpread), default 0.
  Given<double> spread_anode_i0_rel;    // --spread-anode-i0
  Given<double> spread_cathode_i0_rel;  // --spread-cathode-i0
  Given<double> spread_transport_rel;   // --spread-transport
  Given<double> spread_area_rel;        // --spread-area
  Given<bool> fuse_level_only;          // --fuse-level-only (true): the prior combined with the fitted level alone
  Given<double> film_initial_sd_rel;    // --film-initial-sd: the initial film's stated tolerance (relative 1-sigma)
  // best: the voltage sensor's stated offset accuracy (1-sigma), default 0.
  Given<double> voltage_offset_sd_mv;   // --voltage-offset-sd-mv
  // best: the current sensor's stated gain accuracy (1-sigma, percent), default 0.
  Given<double> current_gain_sd_pct;    // --current-gain-sd-pct
  Given<bool> voltage_offset;           // --voltage-offset (true): the sensor offset from CC discharges (off by default)
};

/// An override make_config refused: the option's name (without "--") and why; option nullptr: none.
struct Refusal {
  const char* option;
  const char* reason;
};

/// Whether the profile, with these overrides, runs the state observer / H from the model.
inline bool observer_on(Profile p, const Overrides& o) { return o.resync.or_else(p != Profile::paper); }
inline bool markov_from_model_on(Profile p, const Overrides& o) { return o.h_from_model.or_else(p != Profile::paper); }

/// The first override the profile does not use (with the others given), or {nullptr, nullptr}.
inline Refusal unused_override(Profile p, const Overrides& o) {
  const bool rcsi = p != Profile::best;
  const bool id = p == Profile::best;
  const bool observer = observer_on(p, o);
  const bool bias = rcsi && o.calibrate_bias.or_else(p == Profile::nominal_growth);
  const bool propagate = rcsi && o.propagate_growth.or_else(p == Profile::nominal_growth);
  const char* not_rcsi = "--settings best identifies the film with its growth law (FilmGrowthIdentifier), not with RCSI";
  const char* only_best = "only --settings best identifies the growth law (FilmGrowthIdentifier)";
  const char* no_observer = "the state observer (re-synchronisation) is off";
  struct Use {
    const char* option;
    bool given, used;
    const char* reason;
  };
  const Use uses[] = {
      {"nc", o.nc.given, rcsi, not_rcsi},
      {"h", o.h_v_per_ohm_m2.given, rcsi && !markov_from_model_on(p, o),
       rcsi ? "H is taken from the model at each charge start (--h-from-model or the profile)" : not_rcsi},
      {"h-from-model", o.h_from_model.given, true, ""},
      {"p0", o.p0.given, rcsi, not_rcsi},
      {"p0-y0", o.p0_y0.given, rcsi, not_rcsi},
      {"lambda", o.lambda.given, rcsi, not_rcsi},
      {"eta", o.eta.given, rcsi, not_rcsi},
      {"theta0", o.theta0.given, rcsi, not_rcsi},
      {"r-film-init", o.r_film_init_ohm_m2.given, rcsi,
       "--settings best starts the identified film at the nominal cell's initial film"},
      {"calibrate-bias", o.calibrate_bias.given, rcsi, "--settings best removes the model's design-time bias instead"},
      {"reference-after-resyncs", o.reference_after_resyncs.given, bias && observer,
       "it delays the bias calibration's reference charge, which needs --calibrate-bias and the state observer"},
      {"average", o.average_estimate.given, rcsi, not_rcsi},
      {"propagate-growth", o.propagate_growth.given, rcsi, "--settings best identifies the growth law instead"},
      {"growth-scale", o.growth_scale.given, propagate,
       "it scales the nominal growth law while it propagates the film (--propagate-growth or --settings nominal-growth)"},
      {"no-learning", o.learning.given, true, ""},
      {"warmup", o.warmup_s.given, true, ""},
      {"resync", o.resync.given, true, ""},
      {"no-start-resync", o.resync_at_start.given, observer, no_observer},
      {"resync-window", o.resync_window_ticks.given, observer, no_observer},
      {"resync-current", o.resync_current_a.given, observer, no_observer},
      {"resync-settle-s", o.resync_settle_s.given, observer, no_observer},
      {"no-current-offset", o.current_offset.given, true, ""},
      {"no-area-scale", o.area_scale.given, true, ""},
      {"area-scale-in-model", o.area_scale_model_sees.given, o.area_scale.or_else(p == Profile::best),
       "the electrode-capacity scale is off (--no-area-scale, or a profile without it)"},
      {"no-inventory", o.learn_inventory.given, id, only_best},
      {"model-bias-ohm", o.model_bias_ohm.given, id, only_best},
      {"no-bias-table", o.model_bias_table.given, id, only_best},
      {"no-bias-levels", o.model_bias_levels.given, id, only_best},
      {"bias-table-any-start", o.bias_table_any_start.given, id, only_best},
      {"no-charge-coverage", o.charge_coverage.given, id, only_best},
      {"no-trusted-span", o.trusted_span.given, id, only_best},
      {"trusted-span-end", o.trusted_span_end.given, id, only_best},
      {"relinearise", o.relinearise_inventory.given, id && observer, id ? no_observer : only_best},
      {"no-hold", o.hold_until_settled.given, id, only_best},
      {"hold-restarted-charge", o.hold_restarted_charge.given, id, only_best},
      {"innovation-reject", o.innovation_rejects.given, id, only_best},
      {"innovation-gate", o.innovation_gate.given, id, only_best},
      {"misfit-stop-s", o.misfit_stop_s.given, id, only_best},
      {"inventory-sd", o.inventory_sd.given, id, only_best},
      {"spread-anode-i0", o.spread_anode_i0_rel.given, id, only_best},
      {"spread-cathode-i0", o.spread_cathode_i0_rel.given, id, only_best},
      {"spread-transport", o.spread_transport_rel.given, id, only_best},
      {"spread-area", o.spread_area_rel.given, id, only_best},
      {"fuse-level-only", o.fuse_level_only.given, id, only_best},
      {"film-initial-sd", o.film_initial_sd_rel.given, id, only_best},
      {"voltage-offset-sd-mv", o.voltage_offset_sd_mv.given, id, only_best},
      {"current-gain-sd-pct", o.current_gain_sd_pct.given, id, only_best},
      {"voltage-offset", o.voltage_offset.given, id, only_best},
  };
  for (const Use& u : uses)
    if (u.given && !u.used) return {u.option, u.reason};
  return {nullptr, nullptr};
}

/// The cell's voltage window in the mode detector and the plausibility check.
template <class Config>
void apply_voltage_window(const NominalCell& cell, Config& cfg) {
  using Scalar = decltype(Config::dt_s);
  cfg.detector.v_min = Scalar(cell.lower_voltage_v);
  cfg.detector.v_max = Scalar(cell.upper_voltage_v);
  cfg.voltage_min_v = Scalar(cell.lower_voltage_v - kVoltagePlausibilityMarginV);
  cfg.voltage_max_v = Scalar(cell.upper_voltage_v + kVoltagePlausibilityMarginV);
}

/// The phase currents as C-rates of the cell (NominalCell::nominal_capacity_ah): the paper cell's
/// rest threshold (0.05 A, C/46) and CV end (0.25 A, C/9.2) at its 2.3 Ah, the same fractions of
/// another cell's capacity. The paper cell's own are unchanged (a factor of exactly 1).
/// The plausibility limits (20 A, about 9C of the paper cell) grow with a larger cell but never
/// shrink: they catch a sensor fault, and a small high-power cell's real pulses must pass.
template <class Config>
void apply_capacity_scale(const NominalCell& cell, Config& cfg) {
  using Scalar = decltype(Config::dt_s);
  if (!(cell.nominal_capacity_ah > 0.0)) return;
  const double k = cell.nominal_capacity_ah / paper::kNominalCapacity_ah;
  cfg.detector.rest_current_a = Scalar(static_cast<double>(cfg.detector.rest_current_a) * k);
  cfg.resync_current_a = Scalar(static_cast<double>(cfg.resync_current_a) * k);
  const double k_limit = k > 1.0 ? k : 1.0;
  cfg.current_limit_a = Scalar(static_cast<double>(cfg.current_limit_a) * k_limit);
  cfg.current_step_limit_a = Scalar(static_cast<double>(cfg.current_step_limit_a) * k_limit);
}

// A gap without samples longer than this [s] is a power cycle (BmsCore::Config::power_cycle_after_s):
// an hour of a cycler's current is half to all of a cell's capacity, so a record that stops under
// current and resumes later (a stopped test, the next file, the BMS off) is not credibly interpolated
// over it; shorter gaps are lost samples, caught up on the interpolated current.
constexpr double kPowerCycleGapS = 3600.0;

namespace profiles {

// What best and nominal-growth share: H from the model and the state observer
// (re-synchronisation at power-up, after a power cycle and at each CV end over a 50-tick window).
template <class Config>
void observer(Config& c) {
  using Scalar = decltype(Config::dt_s);
  if constexpr (decltype(c.film_path)::kKind == FilmPathKind::rcsi) c.film_path.markov_from_model = true;
  c.resync_at_cv_end = true;
  c.resync_at_start = true;
  c.resync_window_ticks = 50u;
  c.power_cycle_after_s = Scalar(kPowerCycleGapS);
}

// best: the film, its growth gain and the inventory identified together; 900 s warm-up (the
// reduced model's error settles: 0.1-0.3 mV before); the current sensor's offset removed.
template <class Config>
void best(const NominalCell& cell, Config& c) {
  using Scalar = decltype(Config::dt_s);
  observer(c);
  c.rcsi_warmup_s = Scalar(900);
  c.current_offset = true;
  c.area_scale = true;
  c.area_scale_model_sees = false;  // measured: the film and growth worse with it (docs/results/envelope.md)
  if constexpr (decltype(c.film_path)::kKind == FilmPathKind::identifier) {
    c.film_path.identifier.r_film_nominal_ohm_m2 = Scalar(cell.initial_film_ohm_m2);
    c.film_path.identifier.growth_nominal_ohm_m2_per_a_m3_s = Scalar(cell.growth_ohm_m2_per_a_m3_s);
    c.film_path.model_bias_ohm = Scalar(cell.model_bias_ohm);
    c.film_path.model_bias_table = cell.model_bias_table.template as<Scalar>();
  }
}

// nominal-growth: RCSI's level, 600 s warm-up, bias calibrated on the first charge after a
// re-synchronisation, charge-averaged, carried by the nominal growth law.
template <class Config>
void nominal_growth(const NominalCell& cell, Config& c) {
  using Scalar = decltype(Config::dt_s);
  observer(c);
  c.rcsi_warmup_s = Scalar(600);
  if constexpr (decltype(c.film_path)::kKind == FilmPathKind::rcsi) {
    c.film_path.calibrate_bias = true;
    c.film_path.reference_after_resyncs = 1u;
    c.film_path.average_estimate = true;
    c.film_path.nominal_growth_ohm_m2_per_a_m3_s = Scalar(cell.growth_ohm_m2_per_a_m3_s);
  }
}

}  // namespace profiles

/// The profile over the nominal cell, no overrides. Precondition: Core runs the profile's film
/// path (runs_path_of; CoreFor and with_core_for pick such a core). A core of the other path
/// gets the profile's settings that are not the path's and its own path's defaults; the
/// overload with overrides refuses it.
template <class Core>
typename Core::Config make_config(const NominalCell& cell, Profile profile) {
  using Scalar = decltype(Core::Config::dt_s);
  typename Core::Config cfg{};
  cfg.nominal_inventory_mol = Scalar(cell.inventory_mol);
  if constexpr (Core::FilmPath::kKind == FilmPathKind::rcsi) {
    cfg.film_path.estimator.r_film_init_ohm_m2 = Scalar(cell.initial_film_ohm_m2);
  }
  if (profile == Profile::best) profiles::best(cell, cfg);
  if (profile == Profile::nominal_growth) profiles::nominal_growth(cell, cfg);
  apply_voltage_window(cell, cfg);
  apply_capacity_scale(cell, cfg);
  return cfg;
}

namespace detail {

template <class Field, class T>
void set_if(const Given<T>& g, Field& field) {
  if (g.given) field = static_cast<Field>(g.value);
}

// The observer switched on or off by an override: the defaults an observer starts with
// (power-up re-synchronisation, one re-synchronisation before the reference charge).
template <class Config>
void apply_observer(const Overrides& o, Config& cfg) {
  constexpr bool kRcsi = decltype(cfg.film_path)::kKind == FilmPathKind::rcsi;
  if (o.resync.given) {
    const bool on = o.resync.value;
    const bool was_on = cfg.resync_at_cv_end;
    cfg.resync_at_cv_end = on;
    cfg.resync_at_start = on;
    if constexpr (kRcsi) {
      if (on && !was_on) cfg.film_path.reference_after_resyncs = 1u;
      if (!on) cfg.film_path.reference_after_resyncs = 0u;
    }
  }
  set_if(o.resync_at_start, cfg.resync_at_start);
  set_if(o.resync_window_ticks, cfg.resync_window_ticks);
  set_if(o.resync_current_a, cfg.resync_current_a);
  set_if(o.resync_settle_s, cfg.resync_settle_s);
  if constexpr (kRcsi) set_if(o.reference_after_resyncs, cfg.film_path.reference_after_resyncs);
}

template <class Core>
Refusal apply_rcsi(const NominalCell& cell, const Overrides& o, typename Core::Config& cfg) {
  using Scalar = decltype(Core::Config::dt_s);
  auto& p = cfg.film_path;
  if (o.nc.given && o.nc.value != Core::kNc) return {"nc", "the core was built for another n_c"};
  set_if(o.h_v_per_ohm_m2, p.estimator.markov_v_per_ohm_m2);
  set_if(o.h_from_model, p.markov_from_model);
  set_if(o.p0, p.estimator.p0_u);
  set_if(o.p0, p.estimator.p0_y0);
  set_if(o.p0_y0, p.estimator.p0_y0);
  set_if(o.lambda, p.estimator.lambda);
  set_if(o.eta, p.estimator.eta);
  if (o.theta0.given) {
    if (o.theta0.value.count != 2 * Core::kNc) return {"theta0", "needs 2 n_c values"};
    for (int k = 0; k < 2 * Core::kNc; ++k) p.estimator.theta0(k) = Scalar(o.theta0.value.values[k]);
  }
  set_if(o.r_film_init_ohm_m2, p.estimator.r_film_init_ohm_m2);
  set_if(o.calibrate_bias, p.calibrate_bias);
  set_if(o.average_estimate, p.average_estimate);
  const bool propagate = o.propagate_growth.or_else(p.nominal_growth_ohm_m2_per_a_m3_s != Scalar(0));
  p.nominal_growth_ohm_m2_per_a_m3_s =
      propagate ? Scalar(o.growth_scale.or_else(1.0) * cell.growth_ohm_m2_per_a_m3_s) : Scalar(0);
  return {nullptr, nullptr};
}

template <class Core>
void apply_identifier(const Overrides& o, typename Core::Config& cfg) {
  set_if(o.learn_inventory, cfg.film_path.identifier.learn_inventory);
  set_if(o.model_bias_ohm, cfg.film_path.model_bias_ohm);
  auto& table = cfg.film_path.model_bias_table;
  if (o.model_bias_levels.given && !o.model_bias_levels.value) table.nu_step = 0;  // the nominal level alone
  if (o.model_bias_table.given && !o.model_bias_table.value) table.drop_knots();  // the span has its own ablation
  if (o.bias_table_any_start.given && o.bias_table_any_start.value)
    cfg.film_path.bias_table_start_margin = std::numeric_limits<decltype(cfg.film_path.bias_table_start_margin)>::infinity();
  using TableScalar = decltype(table.nu_step);
  if (o.charge_coverage.given && !o.charge_coverage.value) {  // every charge covered: the defaults
    table.covered_charge_a_min = ModelBiasTables<TableScalar>{}.covered_charge_a_min;
    table.constant_alone_covered = ModelBiasTables<TableScalar>{}.constant_alone_covered;
  }
  if (o.trusted_span_end.given) table.set_trusted_last(static_cast<TableScalar>(o.trusted_span_end.value));
  if (o.trusted_span.given && !o.trusted_span.value)
    table.set_trusted_last(ModelBiasTable<TableScalar>{}.x_trusted_last);  // the default: trusted everywhere
  set_if(o.relinearise_inventory, cfg.film_path.relinearise_inventory);
  set_if(o.hold_until_settled, cfg.film_path.hold_until_settled);
  set_if(o.hold_restarted_charge, cfg.film_path.hold_through_restarted_charge);
  set_if(o.innovation_rejects, cfg.film_path.innovation_rejects);
  set_if(o.innovation_gate, cfg.film_path.innovation_gate);
  set_if(o.misfit_stop_s, cfg.film_path.misfit_stop_s);
  set_if(o.inventory_sd, cfg.film_path.stated_inventory_sd);
  set_if(o.spread_anode_i0_rel, cfg.film_path.spread.anode_i0_rel);
  set_if(o.spread_cathode_i0_rel, cfg.film_path.spread.cathode_i0_rel);
  set_if(o.spread_transport_rel, cfg.film_path.spread.transport_rel);
  set_if(o.spread_area_rel, cfg.film_path.spread.area_rel);
  set_if(o.fuse_level_only, cfg.film_path.fuse_level_only);
  set_if(o.film_initial_sd_rel, cfg.film_path.identifier.stated_film_initial_sd_rel);
  if (o.voltage_offset_sd_mv.given)
    cfg.film_path.voltage_offset_sd_v = static_cast<decltype(cfg.film_path.voltage_offset_sd_v)>(o.voltage_offset_sd_mv.value * 1e-3);
  if (o.current_gain_sd_pct.given)
    cfg.film_path.current_gain_sd = static_cast<decltype(cfg.film_path.current_gain_sd)>(o.current_gain_sd_pct.value * 1e-2);
}

}  // namespace detail

/// The profile over the nominal cell with the overrides; an override the profile does not use
/// (or a value that does not fit the core) is refused and cfg is left as it was.
template <class Core>
Refusal make_config(const NominalCell& cell, Profile profile, const Overrides& o, typename Core::Config& out) {
  Refusal r = unused_override(profile, o);
  if (r.option != nullptr) return r;
  if (!runs_path_of<Core>(profile)) return {"settings", "the core was built for another film path (with_core_for)"};
  typename Core::Config cfg = make_config<Core>(cell, profile);
  if constexpr (Core::FilmPath::kKind == FilmPathKind::rcsi) {
    r = detail::apply_rcsi<Core>(cell, o, cfg);
  } else {
    detail::apply_identifier<Core>(o, cfg);
  }
  if (r.option != nullptr) return r;
  detail::set_if(o.learning, cfg.learning);
  detail::set_if(o.current_offset, cfg.current_offset);
  detail::set_if(o.voltage_offset, cfg.voltage_offset);
  detail::set_if(o.area_scale, cfg.area_scale);
  detail::set_if(o.area_scale_model_sees, cfg.area_scale_model_sees);
  detail::set_if(o.warmup_s, cfg.rcsi_warmup_s);
  detail::apply_observer(o, cfg);
  out = cfg;
  return r;
}

/// A record sampled every sample_step_s [s], coarser than the tick cfg.dt_s (a cycler's export:
/// one sample per sample_step_s / dt_s ticks, the ticks between them missed): what the settings
/// count in received samples (the power-up and CV-end re-synchronisation windows, the warm-up,
/// the mode detector's debounce) is converted to the same span of time, and a rest gap of any
/// length is caught up (catch_up, at most 64 model steps). `bmssim estimate` and the board's
/// replay of a cycler record (target/m4f_blind_main.cpp, BMSMEAS3) both call this.
template <class Config>
void adapt_to_sample_step(Config& cfg, double sample_step_s) {
  using Scalar = decltype(cfg.dt_s);
  const double dt_s = static_cast<double>(cfg.dt_s);
  if (!(sample_step_s > dt_s)) return;
  const double per_sample = dt_s / sample_step_s;
  auto samples = [per_sample](double ticks) {
    const double n = std::round(ticks * per_sample);
    return n > 1.0 ? n : 1.0;
  };
  cfg.resync_window_ticks = static_cast<std::uint32_t>(samples(static_cast<double>(cfg.resync_window_ticks)));
  cfg.detector.debounce_ticks = static_cast<std::uint16_t>(samples(static_cast<double>(cfg.detector.debounce_ticks)));
  cfg.rcsi_warmup_s = static_cast<Scalar>(static_cast<double>(cfg.rcsi_warmup_s) * per_sample);
  cfg.catch_up_max_ticks = 0xFFFFFFFFu;
  cfg.catch_up_max_steps = 64u;
  cfg.catch_up_max_voltage_steps = 64u;
}

/// The paper cell's profile (the board images, the replays, the tests).
template <class Core>
typename Core::Config paper_cell_config(Profile profile) {
  return make_config<Core>(paper_nominal_cell<decltype(Core::Config::dt_s)>(), profile);
}

}  // namespace bms::fw
