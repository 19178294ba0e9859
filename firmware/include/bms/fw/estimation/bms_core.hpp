#pragma once
// The firmware's tick: one call per 0.2 s with the measured voltage and current, returning
// the film-resistance estimate and status. Owns the main-system model, the mode detector
// and the film path; no heap, no exceptions, no globals (the HAL owns the rest).
//
// One tick is the numbered step list at the top of tick() (docs/architecture.md uses the same
// numbers). The parts beyond the paper each sit in their own header with named start, continue
// and stop conditions, and are switched on by Config alone (the profiles of make_config.hpp): LearningGate
// (learning_gate.hpp), StateResync (state_resync.hpp), and the film path.
//
// The film path is a type (film_path.hpp): RcsiFilmPath (the paper's RCSI with BiasCalibration
// and FilmLevel, the paper and nominal-growth profiles) or IdentifierFilmPath (the `best`
// profile's FilmGrowthIdentifier). The tick calls the path's steps and never asks which it is;
// make_config.hpp maps a profile to its path (film_path_of, CoreFor, with_core_for).
// The model answers within the same tick to the u_hat it was given (the film drop is
// algebraic), so the default delay is D = 0 (see bms/fw/estimation/rcsi_estimator.hpp).
//
// MainModel is any type with the ReducedCell interface (init is the caller's business):
//   ModelTickResult<Scalar> step_current(Scalar current_a, Scalar r_film_ohm_m2, Scalar dt_s);
//   ModelTickResult<Scalar> step_voltage(Scalar voltage_v, Scalar r_film_ohm_m2, Scalar dt_s);
//   Scalar li_loss_ah() const;  Scalar li_loss_mol() const;  State state() const;  bool restore(const State&);
//   bool resync(Scalar voltage_v, Scalar current_a, Scalar r_film_ohm_m2, Scalar dt_s, Scalar inventory_mol);
//     (only called by StateResync's steps; a model without an observer returns false)
// The host runs the same core with the full DFN as MainModel (the paper's setting).
#include <cmath>
#include <cstdint>
#include <limits>

#include "bms/fw/estimation/area_scale.hpp"
#include "bms/fw/estimation/current_offset.hpp"
#include "bms/fw/estimation/film_path.hpp"
#include "bms/fw/estimation/fw_status.hpp"
#include "bms/fw/estimation/learning_gate.hpp"
#include "bms/fw/estimation/mode_detector.hpp"
#include "bms/fw/estimation/operating_mode.hpp"
#include "bms/fw/estimation/rcsi_film_path.hpp"
#include "bms/fw/model/reduced_cell.hpp"
#include "bms/fw/estimation/resync_window.hpp"
#include "bms/fw/estimation/state_resync.hpp"
#include "bms/fw/estimation/voltage_offset.hpp"

namespace bms::fw {

template <typename Scalar>
struct TickInput {
  Scalar voltage_v{};
  Scalar current_a{};  // positive = discharge
  bool present{};      // false: no measurement arrived for this tick
  // The cell's measured temperature [K]; 0: none arrived (the model keeps the last accepted one,
  // at power-up the cell's reference temperature).
  Scalar temperature_k = Scalar(0);
};

template <typename Scalar, int Nc>
struct TickOutput {
  Mode mode;
  bool rcsi_active;            // the estimator learned in this tick
  Scalar r_film_est_ohm_m2;    // u_hat in use (held outside CC charge)
  Scalar z_v;                  // y_hat - y of this tick (0 when the sample was not used)
  Scalar model_voltage_v;
  Scalar model_current_a;
  Scalar j_side_a_m3;          // y0_hat
  Scalar li_loss_ah;           // lithium lost to the side reaction (model)
  Scalar theta[2 * Nc];
  // The `best` profile's identified parameters (FilmGrowthIdentifier): initial film, growth-law
  // gain relative to the nominal cell, relative lithium-inventory deviation. 0 in the paper's.
  Scalar film_initial_ohm_m2;
  Scalar growth_gain;
  Scalar inventory_deviation;
  Scalar markov_v_per_ohm_m2;      // H = dV/dR_film of this tick's model step (0 when not stepped)
  Scalar inventory_sensitivity_v;  // S = dV/dnu of this tick (0 unless the identifier learned)
  Scalar growth_ohm_m2;            // the identifier's G (predicted nominal-law growth so far)
  // With the identifier (NaN otherwise): 1-sigma of the film in use (regression and stated model
  // bound); the open-circuit capacity of the identified inventory and its 1-sigma, recomputed
  // when a learning window closes; the innovation test ratio of this learning tick (PX4 EKF2
  // style: > 1 fails the test, bit kModelMisfit; 0 outside learning).
  Scalar r_film_sd_ohm_m2;
  Scalar capacity_ah;
  Scalar capacity_sd_ah;
  Scalar innovation_test_ratio;
  Scalar current_offset_a;     // the current sensor's offset subtracted from the samples (CurrentOffset)
  Scalar voltage_offset_v;     // the voltage sensor's offset subtracted from the samples (VoltageOffset)
  Scalar area_scale;           // the identified electrode-capacity scale (AreaScale; 1 when off)
  StatusWord status;           // bits raised in this tick (estimator bits 0..7, tick 8..15)
  std::uint32_t tick;          // committed ticks
  std::uint8_t newton_iterations;
};

template <typename Scalar = double, typename MainModel = ReducedCell<Scalar>, int Nc = 1, int D = 0,
          typename FilmPathT = RcsiFilmPath<Scalar, Nc, D>>
class BmsCore {
 public:
  using FilmPath = FilmPathT;
  using Detector = ModeDetector<Scalar>;
  using Output = TickOutput<Scalar, Nc>;
  using ModelState = typename MainModel::State;
  static constexpr int kNc = Nc;

  struct Config {
    // What only the film path uses (rcsi_film_path.hpp or identifier_film_path.hpp).
    typename FilmPath::Config film_path{};
    typename Detector::Config detector{};
    Scalar dt_s = Scalar(0.2);
    Scalar voltage_min_v = Scalar(0);
    Scalar voltage_max_v = Scalar(5);
    Scalar current_limit_a = Scalar(20);       // about 9C for the paper cell
    Scalar current_step_limit_a = Scalar(20);  // between two accepted samples
    std::uint16_t stale_limit_ticks = 2;       // more missing ticks than this: frozen + fault bit
    // Ticks without an accepted sample leave the model where it was (the rejected sample
    // must not touch the state), but the cell went on: at the next accepted sample the model
    // first steps over the missed ticks, current-driven on the current interpolated between
    // the last accepted sample and the returning one, film held (plus the predicted growth when
    // that is on), no learning. Without it, each lost frame in CC puts the model 0.2 s of charge
    // behind the cell for the rest of the phase, which RCSI reads as film resistance (measured
    // in the host-in-the-loop: 1 % lost frames took the error from 12 % to 45 %). A gap of up
    // to catch_up_max_ticks is covered (longer: its first catch_up_max_ticks; 0 disables it), in
    // at most catch_up_max_steps backward-Euler steps (a gap of n ticks as n steps when n is
    // small, else as longer steps, which the implicit step takes; the charge moved is exact
    // either way), so the tick's cost is bounded: 8 current-driven steps, about 60 000
    // instructions on the Cortex-M7.
    std::uint32_t catch_up_max_ticks = 3000u;
    std::uint32_t catch_up_max_steps = 8u;
    // A gap in a CV phase is stepped voltage-driven (the cycler held the voltage), and each such
    // step is a Newton solve of up to about 98 000 instructions on the Cortex-M4F: one step keeps
    // the tick within its 300 000-instruction budget.
    std::uint32_t catch_up_max_voltage_steps = 1u;
    // A gap without samples longer than this [s] is a power cycle, not lost frames: the BMS was
    // off and the cell rested (a cycler record that ends under current is a test that was
    // stopped; interpolating its last current over days moves many times the cell's capacity).
    // The model steps over it at rest and, with resync_at_start, re-synchronises to the measured
    // voltage as at power-up. 0: every gap is caught up as lost frames.
    Scalar power_cycle_after_s = Scalar(0);
    // StateResync. Beyond the paper: once per CV phase, when |I| has fallen to resync_current_a, move the
    // model's state to the measured voltage at the nominal lithium inventory minus the
    // model's own lithium loss (MainModel::resync). Removes initial-condition errors and the
    // model's drift before the next CC phase. Off by default (the paper has no observer).
    bool resync_at_cv_end = false;
    // StateResync. Beyond the paper: the same re-synchronisation once, at the first accepted sample after
    // power-up with no restored state (a BMS wakes up from rest: uniform particles). Removes
    // an initial-condition error before the first discharge can clip the model's particle
    // profiles at the stoichiometry limits, which a later uniform shift cannot repair.
    bool resync_at_start = false;
    Scalar resync_current_a = Scalar(0.25);
    // Each re-synchronisation matches a straight line fitted to this many ticks of measured
    // voltage and current (ResyncWindow), taken from the trigger on; 1 = the trigger sample.
    std::uint32_t resync_window_ticks = 1u;
    // The power-up re-synchronisation under a current waits this long [s] for the first seconds'
    // transients to pass (StateResync::follow_power_up); at rest it is at once.
    Scalar resync_settle_s = Scalar(30);
    Scalar nominal_inventory_mol = Scalar(0);
    // LearningGate. Beyond the paper: RCSI learns only after this long in a CC charge. The first seconds
    // after a deep CV discharge are where the reduced model is least accurate (a reaction
    // front it cannot hold); the film estimate is held meanwhile.
    Scalar rcsi_warmup_s = Scalar(0);
    // LearningGate. The control run: every RCSI / RLS update switched off (the model and its observers run).
    bool learning = true;
    // CurrentOffset. Beyond the paper: the current sensor's offset, measured between two CV end
    // points of the same kind (their |I| at resync_current_a), is subtracted from every sample.
    bool current_offset = false;
    // VoltageOffset. Beyond the paper: the voltage sensor's offset, measured from the CC
    // discharge's residual after a fitted CC charge (the film's drop changes sign with the
    // current, an offset does not), is subtracted from every sample. With the identifier only.
    bool voltage_offset = false;
    // AreaScale. Beyond the paper: the electrode-capacity (area) scale measured from the counted
    // charge between two CV ends against the model's pinned anode; the capacity is a C_nom, and
    // with area_scale_model_sees the model runs on I / a too (off in best: measured, the film and
    // growth got worse with it on the sensor set, docs/results/envelope.md "Capacity").
    bool area_scale = false;
    bool area_scale_model_sees = true;
  };

  // The profiles (paper, best, nominal-growth) are built from the nominal cell in one place,
  // bms/fw/config/make_config.hpp; a default Config is the paper's RCSI (with RcsiFilmPath).

  struct State {
    typename FilmPath::State film_path;
    std::uint32_t layout_tag;
    std::uint32_t ticks;
    std::uint32_t stale_ticks;
    std::uint32_t flags;  // bit 0: a sample was accepted
    Scalar last_current_a;
    Scalar last_j_side_a_m3;
    typename LearningGate<Scalar>::State learning;
    typename StateResync<Scalar>::State resync;
    typename CurrentOffset<Scalar>::State offset;
    typename VoltageOffset<Scalar>::State voltage_offset;
    typename AreaScale<Scalar>::State area;
    typename Detector::State detector;
    ModelState model;
  };
  static constexpr std::uint32_t kLayoutTag =
      (0x42u << 24) | (static_cast<std::uint32_t>(sizeof(State) & 0xFFFFu) << 8) |
      static_cast<std::uint32_t>(sizeof(Scalar));

  BmsCore(const Config& config, MainModel& model)
      : config_(config), model_(model), detector_(config.detector), path_(config.film_path, config.dt_s),
        gate_(gate_config(config)), resync_(resync_config(config)),
        offset_(offset_config(config)), voffset_(voltage_offset_config(config)), area_(area_config(config)) {
    last_j_side_ = path_.initial_j_side_a_m3();
  }

  Output tick(const TickInput<Scalar>& in) {
    // One tick, in this order (the numbering docs/architecture.md uses):
    //   1 validate       validate(): finite, voltage and current plausible, no impossible step; a
    //                    rejected or missing sample keeps every state and counts towards staleness
    //   2 catch-up       accept_sample(): the current sensor's offset removed and the measured
    //                    current counted (CurrentOffset); the measured temperature to the model (take_temperature());
    //                    the model steps over the ticks missed since the last accepted sample
    //                    (catch_up(); a gap over power_cycle_after_s at rest); the power-up
    //                    re-synchronisation window opens (also after such a gap)
    //   3 detect mode    ModeDetector::update(): debounced operating mode
    //   4 learning gate  open_gate(): LearningGate (CC charge, warm-up, the path ready; at the
    //                    window's start the path is told: RCSI is reset), the path's BiasCalibration
    //                    stops at the end of a CC charge
    //   5 film in use    FilmPath::film_in_use(): u_hat = RcsiEstimator::predict() inside the window,
    //                    else the held FilmLevel, or the FilmGrowthIdentifier's film
    //   6 model step     step_model(): voltage-driven in CV (debounced and confirmed by this
    //                    sample's class), current-driven otherwise
    //   7 resync         resync_step(): StateResync's window at the end of a CV phase or at power-up;
    //                    CurrentOffset's end points
    //   8 residual       z = y_hat - y; BiasCalibration::collect() over the reference charge
    //                    (FilmPath::collect_reference)
    //   9 learning       learn(): FilmPath::learn, RcsiEstimator::update (or the identifier) from z
    //                    inside the window
    //  10 output         finish_tick()
    StatusWord st = 0u;
    if (!in.present) return held_output(raise_stale(st));                        // 1
    st |= validate(in);
    if ((st & kTickRejectMask) != 0u) return held_output(raise_stale(st));
    const TickInput<Scalar> c = accept_sample(in, st);                           // 2
    const Mode mode = detector_.update(c.voltage_v, c.current_a);                 // 3
    const Gate gate = open_gate(mode);                                            // 4
    const Scalar u = path_.film_in_use(gate.open);                                // 5
    const ModelStep step = step_model(c, mode, u, gate.open);                     // 6
    last_voltage_driven_ = step.voltage_driven;
    if (!step.r.valid) return model_failed(st, gate.open);
    if (!step.r.converged) st |= bit(FwStatus::kModelNotConverged);
    st |= resync_step(c, u, step.voltage_driven);                                 // 7
    follow_offset(in, mode, step.voltage_driven);
    const Scalar z = step.r.voltage_v - c.voltage_v;
    if (gate.reference) path_.collect_reference(z);                               // 8
    const Learned learned = learn(c, u, z, step, gate.open);                      // 9
    follow_voltage_offset(mode, step, z, c.current_a, learned.active);
    return finish_tick(mode, gate, step, z, learned, st | learned.status);        // 10
  }

  State save() const {
    State s{};
    s.film_path = path_.save();
    s.layout_tag = kLayoutTag;
    s.ticks = ticks_;
    s.stale_ticks = stale_ticks_;
    s.flags = have_sample_ ? 1u : 0u;
    s.last_current_a = last_current_;
    s.last_j_side_a_m3 = last_j_side_;
    s.learning = gate_.save();
    s.resync = resync_.save();
    s.offset = offset_.save();
    s.voltage_offset = voffset_.save();
    s.area = area_.save();
    s.detector = detector_.state();
    s.model = model_.state();
    return s;
  }

  static constexpr double kMaxCurrent_a = 1e4;
  static constexpr double kMaxSideCurrent_a_m3 = 1e9;

  // All or nothing: a rejected image changes nothing but the sticky kRestoreRejected bit. Every
  // scalar field is range-checked (finite alone let 1e308 through, and every output then became
  // infinite): the core's currents here, each part's fields by its own restore().
  bool restore(const State& s) {
    auto within = [](Scalar v, Scalar lo, Scalar hi) { return std::isfinite(v) && v >= lo && v <= hi; };
    const bool header_ok = s.layout_tag == kLayoutTag && (s.flags & ~1u) == 0u &&
                           within(s.last_current_a, -Scalar(kMaxCurrent_a), Scalar(kMaxCurrent_a)) &&
                           within(s.last_j_side_a_m3, -Scalar(kMaxSideCurrent_a_m3), Scalar(kMaxSideCurrent_a_m3));
    Detector d = detector_;
    FilmPath p = path_;
    LearningGate<Scalar> g = gate_;
    StateResync<Scalar> rs = resync_;
    CurrentOffset<Scalar> off = offset_;
    VoltageOffset<Scalar> voff = voffset_;
    AreaScale<Scalar> area = area_;
    const ModelState model_backup = model_.state();
    const bool ok = header_ok && d.restore(s.detector) && p.restore(s.film_path) && g.restore(s.learning) &&
                    rs.restore(s.resync, path_.inventory_limit()) && off.restore(s.offset) &&
                    voff.restore(s.voltage_offset) && area.restore(s.area) && model_.restore(s.model);
    if (!ok) {
      model_.restore(model_backup);
      status_ |= bit(FwStatus::kRestoreRejected);
      return false;
    }
    detector_ = d;
    path_ = p;
    gate_ = g;
    resync_ = rs;
    offset_ = off;
    voffset_ = voff;
    area_ = area;
    ticks_ = s.ticks;
    stale_ticks_ = s.stale_ticks;
    have_sample_ = (s.flags & 1u) != 0u;
    last_current_ = s.last_current_a;
    last_j_side_ = s.last_j_side_a_m3;
    held_film_sd_ohm_m2_ = std::numeric_limits<Scalar>::quiet_NaN();  // the next full tick computes it
    last_voltage_driven_ = false;  // not in the image: the next catch-up is current-driven
    return true;
  }

  const FilmPath& film_path() const { return path_; }
  const Detector& detector() const { return detector_; }
  const MainModel& model() const { return model_; }
  StatusWord status() const { return status_ | path_.status(); }
  // The film resistance in use: identified (IdentifierFilmPath), or the held level plus the
  // growth predicted since it was set (RcsiFilmPath).
  Scalar r_film_ohm_m2() const { return path_.r_film_ohm_m2(); }
  std::uint32_t resync_count() const { return resync_.count(); }
  // Ticks that passed without reaching tick() at all (the application's clock or the bus's
  // sequence numbers say how many): counted as ticks without a sample, as `tick` would, without
  // building an output for each.
  void ticks_missed(std::uint32_t ticks) {
    if (ticks != 0u) raise_stale(0u, ticks);
  }
  // Ticks without an accepted sample the model was stepped over since construction (not persisted).
  std::uint32_t catch_up_ticks() const { return catch_up_ticks_; }
  const AreaScale<Scalar>& area_scale() const { return area_; }
  const Config& config() const { return config_; }

 private:
  struct Gate {
    bool open;       // the film is learned in this tick (LearningGate::should_open)
    bool reference;  // this tick's residual goes into the bias calibration
  };
  struct ModelStep {
    ModelTickResult<Scalar> r;
    bool voltage_driven;
    bool probed;        // the path learns from the model's probes in this tick
    Scalar v_probe_v;   // the model's voltage at the probed inventory (probed only)
  };
  using Learned = FilmLearned<Scalar>;

  static typename LearningGate<Scalar>::Config gate_config(const Config& c) {
    return {c.rcsi_warmup_s, c.dt_s, c.learning};
  }
  static typename StateResync<Scalar>::Config resync_config(const Config& c) {
    return {c.resync_at_start, c.resync_at_cv_end, c.resync_current_a, c.resync_window_ticks, c.resync_settle_s};
  }
  static typename CurrentOffset<Scalar>::Config offset_config(const Config& c) {
    typename CurrentOffset<Scalar>::Config o{};
    o.enabled = c.current_offset;
    o.anchor_current_a = c.resync_current_a;
    o.dt_s = c.dt_s;
    return o;
  }
  static typename VoltageOffset<Scalar>::Config voltage_offset_config(const Config& c) {
    typename VoltageOffset<Scalar>::Config o{};
    o.enabled = c.voltage_offset && FilmPath::kKind == FilmPathKind::identifier;
    if constexpr (FilmPath::kKind == FilmPathKind::identifier) o.model_bias_ohm = c.film_path.model_bias_ohm;
    o.dt_s = c.dt_s;
    return o;
  }
  // The least span that measures the area: a share of the nominal cell's open-circuit capacity.
  static typename AreaScale<Scalar>::Config area_config(const Config& c) {
    typename AreaScale<Scalar>::Config a{};
    a.enabled = c.area_scale;
    a.model_sees = c.area_scale_model_sees;
    a.dt_s = c.dt_s;
    if constexpr (kGivesCapacity<MainModel, Scalar>) {
      const Scalar cap_ah = MainModel::open_circuit_capacity_ah(c.nominal_inventory_mol);
      if (std::isfinite(cap_ah)) a.min_span_mol = a.min_span_of_capacity * cap_ah * Scalar(3600.0 / kFaradayC_mol);
    }
    return a;
  }

  // Step 1.
  StatusWord validate(const TickInput<Scalar>& in) const {
    if (!std::isfinite(in.voltage_v) || !std::isfinite(in.current_a)) return bit(FwStatus::kSampleNonFinite);
    StatusWord st = 0u;
    if (in.voltage_v < config_.voltage_min_v || in.voltage_v > config_.voltage_max_v) {
      st |= bit(FwStatus::kVoltageOutOfRange);
    }
    if (std::fabs(in.current_a) > config_.current_limit_a ||
        (have_sample_ && std::fabs(in.current_a - last_current_) > config_.current_step_limit_a)) {
      st |= bit(FwStatus::kCurrentImplausible);
    }
    return st;
  }

  // Step 2: the sample with the current sensor's offset removed (what every later step sees).
  TickInput<Scalar> accept_sample(const TickInput<Scalar>& measured, StatusWord& st) {
    st |= take_temperature(measured.temperature_k);
    const bool first_sample = !have_sample_;
    const bool power_cycle = !first_sample && config_.power_cycle_after_s > Scalar(0) &&
                             static_cast<Scalar>(stale_ticks_) * config_.dt_s > config_.power_cycle_after_s;
    offset_.count(measured.current_a, first_sample ? 0u : stale_ticks_, first_sample, power_cycle);
    voffset_.gap(first_sample ? 0u : stale_ticks_, power_cycle);
    TickInput<Scalar> in = measured;
    in.current_a = offset_.corrected(measured.current_a);
    in.voltage_v = voffset_.corrected(measured.voltage_v);
    area_.count(in.current_a, first_sample || power_cycle ? 0u : stale_ticks_);
    if (!first_sample && stale_ticks_ > 0u) catch_up(stale_ticks_, in, power_cycle);
    stale_ticks_ = 0;
    have_sample_ = true;
    last_current_ = in.current_a;
    last_voltage_ = in.voltage_v;
    resync_.follow_power_up(first_sample || power_cycle, in.current_a, config_.dt_s);
    return in;
  }

  // The model's properties follow the measured temperature (a model that takes none ignores it).
  // 0 means no temperature arrived; a value the model refuses (non-finite, outside its range)
  // leaves the last accepted temperature in use and raises kTemperatureImplausible.
  StatusWord take_temperature(Scalar temperature_k) {
    if (temperature_k == Scalar(0)) return 0u;
    if constexpr (kTakesTemperature<MainModel, Scalar>) {
      if (!model_.set_temperature_k(temperature_k)) return bit(FwStatus::kTemperatureImplausible);
    }
    return 0u;
  }

  // Steps the model over `missed` ticks that had no accepted sample (see
  // Config::catch_up_max_ticks). In a CV phase (the last tick was voltage-driven and the
  // voltage held within the detector's CV band) on the interpolated voltage, as the cycler held
  // it; else on the interpolated current; over a power cycle at rest (zero current).
  void catch_up(std::uint32_t missed, const TickInput<Scalar>& in, bool at_rest) {
    const std::uint32_t gap = missed < config_.catch_up_max_ticks ? missed : config_.catch_up_max_ticks;
    if (gap == 0u || config_.catch_up_max_steps == 0u) return;
    const bool hold_voltage =
        !at_rest && last_voltage_driven_ && std::fabs(in.voltage_v - last_voltage_) <= config_.detector.cv_band_v;
    const Scalar from_a = at_rest ? Scalar(0) : area_.model_current_a(last_current_);
    const Scalar to_a = at_rest ? Scalar(0) : area_.model_current_a(in.current_a);
    std::uint32_t max_steps = config_.catch_up_max_steps;
    if (hold_voltage && config_.catch_up_max_voltage_steps < max_steps) max_steps = config_.catch_up_max_voltage_steps;
    if (max_steps == 0u) return;
    const std::uint32_t steps = gap < max_steps ? gap : max_steps;
    const Scalar ticks_per_step = static_cast<Scalar>(gap) / static_cast<Scalar>(steps);
    const Scalar span = static_cast<Scalar>(missed) + Scalar(1);
    for (std::uint32_t k = 1u; k <= steps; ++k) {
      // Backward Euler: the input at the end of each step's interval.
      const Scalar w = static_cast<Scalar>(k) * ticks_per_step / span;
      const Scalar dt = ticks_per_step * config_.dt_s;
      const ModelTickResult<Scalar> r =
          hold_voltage ? model_.step_voltage(last_voltage_ + w * (in.voltage_v - last_voltage_), r_film_ohm_m2(), dt)
                       : model_.step_current(from_a + w * (to_a - from_a), r_film_ohm_m2(), dt);
      if (!r.valid) return;
      // The film grew over the gap too: without this, each lost frame drops a tick of growth.
      path_.propagate(r.j_side_a_m3, dt);
    }
    catch_up_ticks_ = catch_up_ticks_ + gap < catch_up_ticks_ ? 0xFFFFFFFFu : catch_up_ticks_ + gap;
  }

  // Step 4.
  Gate open_gate(Mode mode) {
    const bool in_cc_charge = mode == Mode::cc_charge;
    if (gate_.phase_ended(in_cc_charge)) path_.charge_ended();
    gate_.count_phase(in_cc_charge);
    Gate g{};
    g.reference = path_.should_collect_reference(in_cc_charge, gate_.warm(), resync_.count());
    g.open = gate_.should_open(in_cc_charge, path_.ready_to_learn());
    if (gate_.should_start(g.open)) path_.window_opens(last_j_side_);
    return g;
  }

  // Step 6.
  ModelStep step_model(const TickInput<Scalar>& in, Mode mode, Scalar u, bool open) {
    const Mode raw = detector_.raw_mode();
    const bool voltage_driven = (raw == Mode::cv_charge || raw == Mode::cv_discharge) && raw == mode;
    const bool probed = path_.learns_from_probes(gate_, open, voltage_driven);
    const Scalar current_a = area_.model_current_a(in.current_a);  // in the nominal cell's units
    const Scalar v_probe =
        probed ? path_.probe(model_, current_a, u, config_.dt_s, config_.nominal_inventory_mol) : Scalar(0);
    const ModelTickResult<Scalar> r = voltage_driven ? model_.step_voltage(in.voltage_v, u, config_.dt_s)
                                                     : model_.step_current(current_a, u, config_.dt_s);
    return ModelStep{r, voltage_driven, probed, v_probe};
  }

  Output model_failed(StatusWord st, bool open) {
    st |= bit(FwStatus::kModelInvalid);
    st |= path_.model_failed(open, last_j_side_);
    gate_.close_tick(open);
    status_ |= st;
    return held_output(st);
  }

  // Step 7: the model is re-synchronised to the path's inventory (identified, or nominal with
  // RCSI) less its own lithium loss.
  StatusWord resync_step(const TickInput<Scalar>& in, Scalar u, bool voltage_driven) {
    resync_.follow_phase(voltage_driven, in.current_a);
    typename StateResync<Scalar>::Fit m{};
    const bool power_up = resync_.power_up_window();
    if (!resync_.collect(in.voltage_v, in.current_a, m)) return 0u;
    const Scalar nu = path_.inventory_deviation();
    const Scalar target_mol = config_.nominal_inventory_mol * (Scalar(1) + nu) - model_.li_loss_mol();
    const typename AreaScale<Scalar>::Pin span_end = area_pin();
    if (!model_.resync(m.voltage_v, area_.model_current_a(m.current_a), u, config_.dt_s, target_mol)) {
      if (!power_up && pin_area(span_end)) path_.relinearise();
      return bit(FwStatus::kResyncFailed);
    }
    bool relinearise = resync_.succeeded(nu, path_.relinearise_inventory());
    if (power_up) area_.unpin();
    if (!power_up) relinearise = pin_area(span_end) || relinearise;
    if (relinearise) path_.relinearise();
    return 0u;
  }

  // Step 7: a CV end is one of AreaScale's pins, re-synchronised or not (the voltage-driven CV
  // phase has held the model's state to the measured voltage). `span_end` is the model before
  // this CV end's re-synchronisation: the span ends at the inventory it started at (AreaScale's
  // header), the next one starts after it. True when the scale the model runs with moved by more
  // than the path's relinearisation limit (what it learned was on the model's old current
  // density and stoichiometry rate).
  bool pin_area(const typename AreaScale<Scalar>::Pin& span_end) {
    if constexpr (kGivesAnodeLithium<MainModel, Scalar>) {
      const Scalar before = area_.scale();
      if constexpr (kGivesCapacity<MainModel, Scalar>) {
        area_.pin(span_end, area_pin(), [](Scalar n) { return MainModel::open_circuit_capacity_ah(n); });
      } else {
        area_.pin(span_end, area_pin());
      }
      return area_.model_sees() && std::fabs(area_.scale() - before) > path_.relinearise_inventory();
    } else {
      (void)span_end;
      return false;
    }
  }

  // The model's lithium as AreaScale pins it (zeros for a model that gives no anode lithium).
  typename AreaScale<Scalar>::Pin area_pin() const {
    typename AreaScale<Scalar>::Pin p{};
    if constexpr (kGivesAnodeLithium<MainModel, Scalar>) {
      p.anode_mol = model_.anode_lithium_mol();
      p.inventory_mol = model_.solid_inventory_mol();
      p.loss_mol = model_.li_loss_mol();
    }
    return p;
  }

  // Step 7: CurrentOffset's end points. When the offset in use moves by more than its dead band
  // (in practice: the first span fused), everything the film path learned was on the old current:
  // it is forgotten, and the re-synchronisation window this CV end opened (the same trigger)
  // places the model at the restarted path's inventory when it fills.
  void follow_offset(const TickInput<Scalar>& measured, Mode mode, bool voltage_driven) {
    const Scalar before_a = offset_.offset_a();
    if (!offset_.follow_phase(voltage_driven, mode == Mode::cv_charge, measured.voltage_v, measured.current_a)) return;
    if (!(std::fabs(offset_.offset_a() - before_a) > offset_.config().deadband_a)) return;
    path_.forget();
    area_.forget();
  }

  // Step 9: VoltageOffset's CC-discharge residual. When the offset in use moves (a discharge's
  // remainder outside the dead band), what the film path learned was on the old voltage: it is
  // forgotten, as at a current offset's change.
  void follow_voltage_offset(Mode mode, const ModelStep& step, Scalar z, Scalar current_a, bool learned) {
    if (!voffset_.config().enabled) return;
    bool holding = false;
    if constexpr (FilmPath::kKind == FilmPathKind::identifier) holding = path_.holding();
    const bool cc_discharge = mode == Mode::cc_discharge && !step.voltage_driven;
    if (voffset_.follow(cc_discharge, holding, learned, z, current_a, step.r.markov_v_per_ohm_m2)) path_.forget();
  }

  // Step 9 (the film's propagation over the tick included).
  Learned learn(const TickInput<Scalar>& in, Scalar u, Scalar z, const ModelStep& step, bool open) {
    const FilmTick<Scalar> t{step.r,       area_.model_current_a(in.current_a), u, z, step.v_probe_v, config_.dt_s,
                             config_.nominal_inventory_mol, open, step.probed, area_.scale(),
                             area_.span_inventory_mol()};
    return path_.learn(t, model_, gate_, resync_);
  }

  // Step 10.
  Output finish_tick(Mode mode, Gate gate, const ModelStep& step, Scalar z, const Learned& learned, StatusWord st) {
    gate_.close_tick(gate.open);
    last_j_side_ = step.r.j_side_a_m3;
    ++ticks_;
    const Scalar film_sd = path_.film_sd_ohm_m2();
    held_film_sd_ohm_m2_ = film_sd;
    Output out = base_output(mode, film_sd);
    out.rcsi_active = learned.active;
    out.r_film_est_ohm_m2 = r_film_ohm_m2();  // u itself, or its charge average, plus predicted growth
    out.z_v = z;
    out.model_voltage_v = step.r.voltage_v;
    out.model_current_a = area_.cell_current_a(step.r.current_a);
    out.j_side_a_m3 = step.r.j_side_a_m3;
    out.markov_v_per_ohm_m2 = step.r.markov_v_per_ohm_m2;
    out.inventory_sensitivity_v = learned.inventory_sensitivity_v;
    out.innovation_test_ratio = path_.innovation_test_ratio();
    out.newton_iterations = step.r.newton_iterations;
    out.status = st;
    status_ |= st;
    return out;
  }

  StatusWord raise_stale(StatusWord st, std::uint32_t ticks = 1u) {
    stale_ticks_ = stale_ticks_ + ticks < stale_ticks_ ? 0xFFFFFFFFu : stale_ticks_ + ticks;
    if (stale_ticks_ > config_.stale_limit_ticks) st |= bit(FwStatus::kMeasurementStale);
    status_ |= st;
    return st;
  }

  Output base_output(Mode mode, Scalar film_sd) const {
    Output o{};
    o.mode = mode;
    o.rcsi_active = false;
    o.r_film_est_ohm_m2 = r_film_ohm_m2();
    o.z_v = Scalar(0);
    o.model_voltage_v = Scalar(0);
    o.model_current_a = last_current_;
    o.j_side_a_m3 = last_j_side_;
    o.li_loss_ah = model_.li_loss_ah();
    path_.write_outputs(o, film_sd);  // theta, the identified parameters and their uncertainties
    o.markov_v_per_ohm_m2 = Scalar(0);
    o.inventory_sensitivity_v = Scalar(0);
    o.innovation_test_ratio = Scalar(0);
    o.current_offset_a = offset_.offset_a();
    o.voltage_offset_v = voffset_.offset_v();
    o.area_scale = area_.scale();
    o.tick = ticks_;
    o.newton_iterations = 0;
    o.status = 0u;
    return o;
  }

  Output held_output(StatusWord st) const {
    Output o = base_output(detector_.mode(), held_film_sd_ohm_m2_);
    o.status = st;
    return o;
  }

  Config config_;
  MainModel& model_;
  Detector detector_;
  FilmPath path_;
  LearningGate<Scalar> gate_;
  StateResync<Scalar> resync_;
  CurrentOffset<Scalar> offset_;
  VoltageOffset<Scalar> voffset_;
  AreaScale<Scalar> area_;
  Scalar last_current_ = Scalar(0);
  Scalar last_voltage_ = Scalar(0);   // the last accepted sample's (catch-up in CV; not persisted)
  bool last_voltage_driven_ = false;  // the last tick's model step was voltage-driven
  Scalar last_j_side_ = Scalar(0);
  std::uint32_t ticks_ = 0u;
  std::uint32_t stale_ticks_ = 0u;
  bool have_sample_ = false;
  std::uint32_t catch_up_ticks_ = 0u;
  StatusWord status_ = 0u;
  // The film's sd of the last full tick, reported by held ticks: nothing it depends on moves
  // without a full tick, and computing it (software double on the M4F) in each of a gap's
  // missed ticks took the catch-up probe from 135 000 to 1.1 million instructions. NaN until
  // the first full tick after power-up or a restore.
  Scalar held_film_sd_ohm_m2_ = std::numeric_limits<Scalar>::quiet_NaN();
};

}  // namespace bms::fw
