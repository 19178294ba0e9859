#pragma once
// The `best` profile's film path: the film, its growth gain relative to the nominal law and the
// cell's lithium inventory identified together in output-error form (FilmGrowthIdentifier)
// against the reduced model's design-time bias, with an innovation test of the fit, the film's
// 1-sigma (regression, stated model bound, temperature sensor) and the open-circuit capacity of
// the identified inventory. The interface is film_path.hpp's; everything the identifier's path
// needs and RCSI's does not lives in its Config.
// Header-only C++17: no heap, no exceptions, no RTTI.
#include <cmath>
#include <cstdint>
#include <limits>

#include "bms/fw/estimation/film_growth_identifier.hpp"
#include "bms/fw/estimation/film_path.hpp"
#include "bms/fw/estimation/learning_gate.hpp"
#include "bms/fw/estimation/state_resync.hpp"
#include "bms/fw/model/model_bias_table.hpp"
#include "bms/fw/model/reduced_cell.hpp"

namespace bms::fw {

template <typename Scalar = double>
class IdentifierFilmPath {
 public:
  static constexpr FilmPathKind kKind = FilmPathKind::identifier;
  using Identifier = FilmGrowthIdentifier<Scalar>;

  struct Config {
    static constexpr FilmPathKind kKind = FilmPathKind::identifier;
    typename Identifier::Config identifier{};
    // The reduced model's voltage bias in CC charge per ampere of charge current, computed once
    // at design time against a converged DFN of the nominal cell (never against the cell in use;
    // scripts/calibrate-model-bias.sh). In CC a bias is collinear with the film, so without it the
    // film would carry it (about 2.7 % of R_film for the paper cell).
    Scalar model_bias_ohm = Scalar(0);
    // The state-of-charge-dependent part of the same bias (ModelBiasTable over the model's mean
    // anode stoichiometry, and over the model's inventory where it has levels: ModelBiasTables),
    // added to model_bias_ohm; off by default (the constant alone). A model that does not give its
    // mean anode stoichiometry runs on the constant alone.
    ModelBiasTables<Scalar> model_bias_table{};
    // The table's start condition: it holds the reduced model's error along charges that began
    // at the bottom of the window after a full discharge and rest, and that error depends on how
    // long the charge has run (the particles' gradients), not on the stoichiometry alone. A charge
    // whose learning opens more than this fraction of the table's span above its first knot
    // (where the calibration's charges opened) began elsewhere: it runs on the constant alone.
    // Infinity: the table for every charge (the ablation, --bias-table-any-start).
    // Start condition of a charge's fusion: a charge the calibration does not cover
    // (ModelBiasTables::covers: its current, or the constant alone where the table is off for it)
    // is not learned from (kInnovationRejected); the film goes on with its growth law. Its misfit
    // is not the film's; learning the inventory alone from it (the film considered, not moved)
    // was tried and put the misfit into the inventory (an LCO truth 0.9 % rich fitted at 3.8 %).
    Scalar bias_table_start_margin = Scalar(0.1);
    // A re-synchronisation that moves the model's inventory by more than this (relative)
    // restarts the film parameters' learning (FilmGrowthIdentifier::relinearise).
    Scalar relinearise_inventory = Scalar(1e-3);
    // From the start (the prior) and after a relinearisation the outputs (film, its sd, the
    // identified parameters, the capacity) stay those of the identifier as it was, propagated
    // with the film's growth, until the (re)started one has settled (FilmGrowthIdentifier::settled): its first seconds
    // of data swing the film tens of percent along the film-growth-inventory direction the
    // prior leaves open. The model keeps the restarted identifier's film (film_in_use).
    bool hold_until_settled = true;
    // A restart of a fitted identifier (relinearisation, or the current sensor's offset changed)
    // is held through the whole CC charge it restarts in, not only until the regression variance
    // is within the model bound: with a current gain the charge's counted charge runs ahead of (or
    // behind) the cell, and a fit with its inventory free reads that ramp as inventory and the film
    // compensates (measured: 8-9 % of the film for most of the restarted charge under a 0.5 % gain,
    // the regression's own sd of the inventory then far below its stated bound), coming back only
    // near the charge's end. The restarted fit is reported from the end of that charge on. The
    // start from the prior (power-up) is held as before (there is no fitted value to hold).
    // Off by default (--hold-restarted-charge): where the inventory settles over several charges
    // (About:Energy's flat LFP curve: every CV end restarts the fit for four charges) each charge
    // then reports the previous charge's end (measured, film of cycles 3-5: 5.5 % held, 1.3 % not;
    // a 10 mA offset without a gain, cycle 3: 0.76 % held, 0.41 % not), and the gain truths' film
    // it helps stays above 2 % on set 5 either way (docs/results/envelope.md).
    bool hold_through_restarted_charge = false;
    // Innovation test of the learning ticks (as PX4 EKF2 gates a fusion): the residual less the
    // design-time bias, averaged over innovation_time_constant_s (an exponential mean restarted
    // at each learning window, so the sensor noise averages out), is compared with
    // innovation_gate x innovation_sd_v, the reduced model's own residual in CC charge at the
    // right film (0.29 mV rms against the converged DFN, docs/results/firmware-model.md).
    // test ratio = (mean / (gate sd))^2; above 1 the model does not fit the cell (kModelMisfit).
    // It only reports: the learning goes on (the estimate's validity is the caller's decision).
    Scalar innovation_time_constant_s = Scalar(60);
    Scalar innovation_sd_v = Scalar(3e-4);
    Scalar innovation_gate = Scalar(5);
    // Innovation consistency check on the fusion (PX4 EKF2 rejects a measurement whose test ratio
    // exceeds 1): the regression's own a-priori innovation (FilmGrowthIdentifier::innovation_v:
    // the residual less what the fitted film, gain and inventory explain), averaged as above, is
    // compared with the same gate; a tick above it is not learned from. Where the reduced model
    // leaves the cell (the knee at a charge's end on a flat-OCP cell: 1-100 mV) its residual is
    // not film, and fitted it moved the film's level by several percent in the charge's last
    // minutes, differently in each charge as the inventory settled. false: every tick is learned.
    bool innovation_rejects = false;
    // Stop condition of a charge's fusion (PX4 EKF2 stops fusing a source whose innovation test
    // keeps failing): once the residual less the bias and less the part the fitted inventory
    // explains (placed_test_fails: the model moves to the fitted inventory only at the next
    // re-synchronisation), averaged and gated as the innovation test above, has failed for more
    // than misfit_stop_s of a charge's learning ticks within the trusted span, the fit the charge
    // started with did not explain it: the fit goes back to the last one a charge verified (the
    // prior before any) and learns nothing more until the next charge. G, the cell's history, is
    // kept. Tested only from a settled fit (or after a first stop: misfit_stop). The plain
    // innovation test is not the stop's: a cell whose inventory is 1 % off fails it for the whole
    // charge (the paper cell's blind set 1).
    // Off by default (0; --misfit-stop-s 120 turns it on): it leaves every cell's nominal set 1
    // bit for bit and moves 4 of 10 truths of About:Energy's spread set a little; it does not stop
    // that set's run-away, which comes in the first charge from the prior and then explains the
    // later charges (docs/results/envelope.md).
    Scalar misfit_stop_s = Scalar(0);
    // The cell's stated lithium-inventory tolerance (relative 1-sigma; 0: not tested). A charge's
    // fit (tested at the next charge's start: within a charge from the prior the inventory swings
    // further on a nominal cell) whose inventory leaves kInventoryGateSd of it is not plausible for
    // this cell: its kinetics are not the model's (from the prior the first charge runs the
    // inventory towards the limit and the film with it, and placed there the model explains the
    // later charges, so no residual test sees it). The fit goes back to the last verified one (the
    // prior before any) and nothing more is learned until a restart (kInnovationRejected on every
    // learning tick): the model does not describe this cell.
    Scalar stated_inventory_sd = Scalar(0);
    // 1-sigma of the temperature sensor [K]: in CC charge a temperature error is nearly collinear
    // with the film (measured about 5 % of the paper cell's film per K), so it enters the film's sd
    // as |dV/dT / H| x this (the model's sensitivity, probed at each learning tick). A stated
    // accuracy of the sensor, not learned; 0 leaves it out.
    Scalar temperature_sd_k = Scalar(0.2);
    // The cell's stated parameter spread (relative 1-sigma, StatedSpread): in CC charge the anode's
    // and the cathode's charge-transfer, the transport overpotentials and the film add almost
    // collinearly, so a cell whose kinetics or transport are known only to a lot tolerance has a film
    // level known no better. Each enters the film's sd as its voltage 1-sigma / H (the reduced
    // model's closed form at each learning tick, ReducedCell::spread_voltage_sd_v). A stated
    // tolerance, never learned; 0 (a characterised cell) leaves it out.
    StatedSpread<Scalar> spread{};
    // With a stated spread, what the prior is combined with: the whole fitted film (false, the
    // default), whose growth then leans to the nominal law as the spread widens; or the fitted
    // level alone (true), against the prior's level carrying the fit's growth
    // (FilmGrowthIdentifier::prior_level_film_ohm_m2): a spread offsets a cell's level for its
    // whole life, not its growth, so the growth stays the fit's. Better only where the fit's
    // growth is (the paper cell; docs/results/envelope.md): off by default.
    bool fuse_level_only = false;
    // 1-sigma of the voltage sensor's offset [V] (the analog front end's stated accuracy, never
    // this unit's actual offset): in CC charge a constant voltage offset is read as a resistance
    // (measured about 30 % of the paper cell's film per mV at 1C), so it enters the fitted level's
    // sd as this / |H| in quadrature, as the stated spread does (not on the held prior: the prior
    // reads no voltage). A stated accuracy, not learned; 0 leaves it out.
    Scalar voltage_offset_sd_v = Scalar(0);
    // Relative 1-sigma of the current sensor's gain (the front end's stated accuracy, never this
    // unit's actual gain): the capacity is counted in the sensor's amperes (AreaScale), so a gain
    // g moves it by g, which no measurement of I and V can tell from the electrode area. It
    // enters capacity_sd_ah as this x the capacity in quadrature. A stated accuracy, not learned;
    // 0 leaves it out.
    Scalar current_gain_sd = Scalar(0);
  };

  // Trivially copyable, for the NVM image.
  struct State {
    typename Identifier::State identifier;
  };

  // The prior (the nominal cell's film, law and inventory) is held as a relinearised one is.
  IdentifierFilmPath(const Config& c, Scalar /*dt_s*/)
      : c_(c),
        identifier_(c.identifier),
        held_(c.identifier),
        holding_(c.hold_until_settled),
        verified_fit_(identifier_.fit()) {}

  Scalar initial_j_side_a_m3() const { return Scalar(0); }

  // Step 4: no bias calibration, no reset at the window's start (the identifier keeps the
  // information of every charge; its window starts in learn()).
  void charge_ended() {
    if (restarted_charge_ && learned_since_restart_) {
      restarted_charge_ = false;
      holding_ = false;  // the restarted fit has seen a whole charge (its variance may still exceed the bound: g)
    }
  }
  bool ready_to_learn() const { return true; }
  bool should_collect_reference(bool /*in_cc_charge*/, bool /*warm*/, std::uint32_t /*resyncs*/) const { return false; }
  void window_opens(Scalar /*last_j_side_a_m3*/) {}

  // Step 5: the identified film.
  Scalar film_in_use(bool /*open*/) const { return identifier_.film_ohm_m2(); }

  // Step 6: the identifier learns in the open window when learning is on and the model is
  // current-driven; then the model is probed at a shifted inventory (S = dV/dnu) and, with a
  // stated temperature-sensor accuracy, at +kTemperatureProbeK.
  bool learns_from_probes(const LearningGate<Scalar>& gate, bool open, bool voltage_driven) const {
    return gate.should_identify(open, voltage_driven);
  }
  template <class Model>
  Scalar probe(Model& model, Scalar current_a, Scalar u, Scalar dt_s, Scalar inventory_mol) {
    const Scalar v_probe = model.inventory_probe_voltage(current_a, u, dt_s, kInventoryProbe * inventory_mol);
    if constexpr (kProbesTemperature<Model, Scalar>) {
      if (c_.temperature_sd_k > Scalar(0)) v_warm_v_ = model.temperature_probe_voltage(current_a, u, dt_s, kTemperatureProbeK);
    }
    return v_probe;
  }

  // Step 7: the model is re-synchronised to the identified inventory; a move larger than
  // relinearise_inventory restarts the learning of the film's parameters.
  Scalar inventory_deviation() const { return identifier_.inventory_deviation(); }
  Scalar relinearise_inventory() const { return c_.relinearise_inventory; }
  void relinearise() {
    hold_reported();
    identifier_.relinearise();
  }
  // The current the model and the identifier see changed (the sensor's offset in use moved):
  // what was learned before carries the old offset (measured: 5 mA took a charge's identified
  // inventory 0.24 % off, and the next re-synchronisation's move from it restarted the fit once
  // more). Restart from the prior; the re-synchronisation at this CV end places the model at the
  // prior's inventory. The outputs are held as at a relinearisation.
  void forget() {
    hold_reported();
    identifier_.restart_from_prior();
    verified_fit_ = identifier_.fit();  // what was verified carries the old offset too
  }
  // Keeps reporting the fitted values while a restarted fit settles (Config::hold_until_settled).
  void hold_reported() {
    if (!c_.hold_until_settled || (holding_ && held_is_prior_)) return;
    restarted_charge_ = c_.hold_through_restarted_charge;  // also when a restart comes while holding
    learned_since_restart_ = false;
    if (holding_) return;
    held_ = identifier_;
    holding_ = true;
    held_is_prior_ = false;
  }
  // The identifier whose values are reported: the held one until the restarted one settles.
  const Identifier& reported() const { return holding_ ? held_ : identifier_; }
  bool holding() const { return holding_; }
  Scalar inventory_limit() const { return c_.identifier.inventory_limit; }

  // Step 8: nothing (no reference charge).
  void collect_reference(Scalar /*z_v*/) {}

  // Step 9: the film, its growth gain and the inventory in output-error form.
  template <class Model>
  FilmLearned<Scalar> learn(const FilmTick<Scalar>& t, const Model& model, LearningGate<Scalar>& gate,
                            const StateResync<Scalar>& resync) {
    FilmLearned<Scalar> l{0u, false, Scalar(0)};
    innovation_ratio_ = Scalar(0);
    if (t.probed) {
      const bool start = gate.should_start_identifying(t.probed);
      if (start) identifier_.begin_charge();
      bias_nu_ = resync.inventory_deviation_model();  // the levels' abscissa: where the model is placed
      const Scalar x_neg = mean_stoich_of(model);  // once: the bias table and the trusted span read it
      if (start) {
        table_in_charge_ = table_starts_at(x_neg);
        covered_charge_ = c_.model_bias_table.covers(-t.current_a, table_in_charge_);
      }
      const auto table = bias_table_at(x_neg);
      const Scalar bias_ohm = c_.model_bias_ohm + table.ohm;
      const StatusWord misfit = innovation_test(t.z_v + bias_ohm * t.current_a, start, t.dt_s);
      l.status |= misfit;
      // The residual's sensitivity to the inventory: the model's, and the bias's where it has levels
      // (the bias is evaluated where the model is placed; an inventory the fit moves moves it too).
      l.inventory_sensitivity_v = (t.v_probe_v - t.r.voltage_v) / kInventoryProbe + t.current_a * table.slope;
      const Scalar per_k = (v_warm_v_ - t.r.voltage_v) / (kTemperatureProbeK * t.r.markov_v_per_ohm_m2);
      if (c_.temperature_sd_k > Scalar(0) && std::isfinite(per_k)) film_per_kelvin_ohm_m2_ = std::fabs(per_k);
      update_spread(model, t.r);
      update_voltage_offset_term(t.r.markov_v_per_ohm_m2);
      const Scalar nu_model = resync.inventory_deviation_model(), bias_v = -bias_ohm * t.current_a;
      if (start) stopped_in_charge_ = false;
      const bool past_span = beyond_trusted_span(x_neg);  // a tick past it is not fused: not tested
      const bool tested = covered_charge_ && !past_span;
      misfit_stop(start, tested && placed_test_fails(t, l.inventory_sensitivity_v, nu_model, bias_v, start), t.dt_s);
      if (!tested || misfit_stopped_ || fusion_rejected(t, l.inventory_sensitivity_v, nu_model, bias_v, start)) {
        l.status |= bit(FwStatus::kInnovationRejected);
      } else {
        l.status |= identifier_.learn(t.u_ohm_m2, t.z_v, t.r.markov_v_per_ohm_m2, l.inventory_sensitivity_v,
                                      nu_model, bias_v);
        l.active = (l.status & kIdentifierRejectMask) == 0u;
      }
      learned_since_restart_ = true;
      if (holding_ && !restarted_charge_ && identifier_.settled()) holding_ = false;
    }
    propagate(t.r.j_side_a_m3, t.dt_s);
    gate.identified(t.probed);
    update_capacity(model, t.probed, t.nominal_inventory_mol, t.area_scale, t.area_inventory_mol);
    return l;
  }

  void propagate(Scalar j_side_a_m3, Scalar dt_s) {
    identifier_.propagate(j_side_a_m3, dt_s);
    if (holding_) held_.propagate(j_side_a_m3, dt_s);
  }
  StatusWord model_failed(bool /*open*/, Scalar /*last_j_side_a_m3*/) { return 0u; }

  // The reported film: the identified one; with a stated spread, once a fitted level is reported,
  // the inverse-variance combination of the prior and that fit (fused_with_prior).
  Scalar r_film_ohm_m2() const {
    const Scalar fit = reported().film_ohm_m2();
    return fuses_with_prior() ? fused_with_prior(fit, fitted_sd_ohm_m2()).film_ohm_m2 : fit;
  }
  // The reported film's 1-sigma: the fitted level's (fitted_sd_ohm_m2), or with a stated spread
  // that of its combination with the prior, 1 / sqrt(1 / sd_prior^2 + 1 / sd_fit^2).
  Scalar film_sd_ohm_m2() const {
    const Scalar sd = fitted_sd_ohm_m2();
    return fuses_with_prior() ? fused_with_prior(reported().film_ohm_m2(), sd).sd_ohm_m2 : sd;
  }
  // The fitted level's 1-sigma: the identifier's (regression and model bound) and the temperature
  // sensor's, |dV/dT / H| x temperature_sd_k, in quadrature.
  // With a stated spread or voltage sensor accuracy, their film equivalents too, where the
  // reported film is fitted to the voltage (their collinear share is the fit's); the held prior's
  // sd is the prior's.
  Scalar fitted_sd_ohm_m2() const {
    const Scalar sd = held_prior_stated() ? held_.prior_film_sd_ohm_m2() : reported().film_sd_ohm_m2();
    const Scalar t = film_per_kelvin_ohm_m2_ * c_.temperature_sd_k;
    const Scalar with_t = std::isfinite(t) ? std::sqrt(sd * sd + t * t) : sd;
    const bool spread = film_spread_ohm_m2_ > Scalar(0), voltage = film_voltage_offset_ohm_m2_ > Scalar(0);
    if (!(spread || voltage) || (holding_ && held_is_prior_)) return with_t;
    Scalar v = with_t * with_t;
    if (spread) v += film_spread_ohm_m2_ * film_spread_ohm_m2_;
    if (voltage) v += film_voltage_offset_ohm_m2_ * film_voltage_offset_ohm_m2_;
    return std::sqrt(v);
  }
  // The held prior with the initial film's stated tolerance: its sd is the stated prior's
  // (FilmGrowthIdentifier::prior_film_sd_ohm_m2), not the regression's weak prior, which a held
  // prior that never learned otherwise reports.
  bool held_prior_stated() const {
    return holding_ && held_is_prior_ && c_.identifier.stated_film_initial_sd_rel > Scalar(0);
  }
  // With a stated spread the fitted level is told from the prior only to within the spread's
  // collinear share: where that is wider than the prior's own sd the fit says less than the
  // prior. Both are independent estimates of the same film (the fit's regression prior is weak:
  // Identifier::Config, the data decide), so the level reported is their inverse-variance mean.
  // Without a stated spread (a characterised cell), or while the prior itself is held, nothing.
  bool fuses_with_prior() const {
    return c_.spread.any() && film_spread_ohm_m2_ > Scalar(0) && !(holding_ && held_is_prior_);
  }
  struct Level {
    Scalar film_ohm_m2;
    Scalar sd_ohm_m2;
  };
  // (sd_f^2 prior + sd_p^2 fit) / (sd_p^2 + sd_f^2), sd_p sd_f / sqrt(sd_p^2 + sd_f^2): the
  // inverse-variance mean and its 1-sigma (Config::fuse_level_only says which prior). A prior sd
  // that is not positive and finite: the fit.
  Level fused_with_prior(Scalar fit_ohm_m2, Scalar fit_sd_ohm_m2) const {
    const bool level = c_.fuse_level_only;
    const Scalar p = level ? reported().prior_level_film_ohm_m2() : identifier_.prior_film_ohm_m2();
    const Scalar sp = level ? reported().prior_level_film_sd_ohm_m2() : identifier_.prior_film_sd_ohm_m2();
    const Scalar vp = sp * sp, vf = fit_sd_ohm_m2 * fit_sd_ohm_m2;
    if (!(sp > Scalar(0)) || !std::isfinite(vp) || !std::isfinite(vf) || !(vp + vf > Scalar(0)))
      return Level{fit_ohm_m2, fit_sd_ohm_m2};
    return Level{(vf * p + vp * fit_ohm_m2) / (vp + vf), sp * fit_sd_ohm_m2 / std::sqrt(vp + vf)};
  }
  // The stated spread's film equivalent [ohm m2] at the last learning tick (0 without one).
  Scalar film_spread_ohm_m2() const { return film_spread_ohm_m2_; }
  // The voltage sensor's stated offset accuracy as a film [ohm m2], last learning tick (0 without).
  Scalar film_voltage_offset_ohm_m2() const { return film_voltage_offset_ohm_m2_; }
  Scalar innovation_test_ratio() const { return innovation_ratio_; }
  // This charge's fusion was stopped by its placed-residual test (Config::misfit_stop_s).
  bool misfit_stopped_in_charge() const { return misfit_stopped_; }
  // The identified parameters and their uncertainties. theta: the ARX subsystem RCSI fits is not
  // used here; it reads as the hold RCSI starts from, [M1 = 1, 0, ...] (the identifier's film
  // is an integrator too: M1 = 1).
  template <class Output>
  void write_outputs(Output& o, Scalar film_sd_ohm_m2) const {
    bool first = true;
    for (auto& th : o.theta) {
      th = first ? Scalar(1) : Scalar(0);
      first = false;
    }
    const Identifier& id = reported();
    o.film_initial_ohm_m2 = id.initial_film_ohm_m2();
    o.growth_gain = id.gain();
    o.inventory_deviation = id.inventory_deviation();
    o.growth_ohm_m2 = id.growth_ohm_m2();
    o.r_film_sd_ohm_m2 = film_sd_ohm_m2;
    o.capacity_ah = capacity_ah_;
    o.capacity_sd_ah = capacity_sd_ah_;
  }
  StatusWord status() const { return 0u; }

  // Not persisted: the capacity is recomputed at the first tick after a restore, the innovation
  // mean restarts with the next learning window.
  State save() const { return State{identifier_.save()}; }
  bool restore(const State& s) {
    Identifier id = identifier_;
    if (!id.restore(s.identifier)) return false;
    identifier_ = id;
    capacity_ah_ = std::numeric_limits<Scalar>::quiet_NaN();  // recomputed from the restored inventory
    identifying_ = false;
    holding_ = false;  // not in the image: the restored identifier is reported
    fit_at_charge_ = identifier_.fit();  // a stop before the next charge's start goes back to it
    verified_fit_ = fit_at_charge_;      // it explained the charges it was learned from
    misfit_armed_ = false;
    return true;
  }

  const Identifier& identifier() const { return identifier_; }
  const Config& config() const { return c_; }

  // The design-time bias per ampere of charge current at the model's state [ohm]: the constant,
  // plus the table at the model's mean anode stoichiometry where the table is on.
  template <class Model>
  Scalar model_bias_ohm_of(const Model& model) const {
    return model_bias_ohm_at(mean_stoich_of(model));
  }
  Scalar model_bias_ohm_at(Scalar x_neg) const { return c_.model_bias_ohm + bias_table_at(x_neg).ohm; }
  // The table's part of the bias and its slope over the inventory at the model's state (0 and 0:
  // no table, or no stoichiometry).
  typename ModelBiasTables<Scalar>::Reading bias_table_at(Scalar x_neg) const {
    if (!c_.model_bias_table.on() || std::isnan(x_neg) || !table_in_charge_) return {Scalar(0), Scalar(0)};
    return c_.model_bias_table.read(x_neg, bias_nu_);
  }
  // The model's mean anode stoichiometry where the table or the trusted span needs it (NaN: a
  // model without one, or neither needs it).
  template <class Model>
  Scalar mean_stoich_of(const Model& model) const {
    if constexpr (kGivesStoichiometry<Model, Scalar>) {
      if (c_.model_bias_table.on() || c_.model_bias_table.has_trusted_span()) return model.mean_stoich_neg();
    } else {
      (void)model;
    }
    return std::numeric_limits<Scalar>::quiet_NaN();
  }

 private:
  // The exponential mean of e over innovation_time_constant_s (restarted at a learning window's
  // start) and its test ratio against the gate: (mean / (gate sd))^2.
  Scalar averaged_ratio(Scalar& mean_v, Scalar e, bool window_start, Scalar dt_s) const {
    const Scalar a = dt_s / (c_.innovation_time_constant_s + dt_s);
    mean_v = window_start ? e : mean_v + a * (e - mean_v);
    const Scalar limit = c_.innovation_gate * c_.innovation_sd_v;
    return (mean_v / limit) * (mean_v / limit);
  }

  // The innovation test (Config::innovation_*) on this learning tick's bias-corrected residual.
  StatusWord innovation_test(Scalar z_corrected_v, bool window_start, Scalar dt_s) {
    if (!(c_.innovation_sd_v > Scalar(0)) || !std::isfinite(z_corrected_v)) return 0u;
    innovation_ratio_ = averaged_ratio(innovation_mean_v_, z_corrected_v, window_start, dt_s);
    return innovation_ratio_ > Scalar(1) ? bit(FwStatus::kModelMisfit) : 0u;
  }

  // The stop condition's test (Config::misfit_stop_s): the residual less the bias and less what
  // the fitted inventory explains where the model is not yet placed at it, S (nu_model - nu_fit),
  // averaged and gated as the innovation test is. A film the fit has is gone from the residual
  // (the model runs on it); a residual no film explains stays, even where the film is held at
  // its admissible floor (the regression's own innovation then vanishes: the fit takes it all).
  bool placed_test_fails(const FilmTick<Scalar>& t, Scalar s_v, Scalar nu_model, Scalar bias_v, bool window_start) {
    if (!(c_.misfit_stop_s > Scalar(0)) || !(c_.innovation_sd_v > Scalar(0))) return false;
    const Scalar placement_v = std::isfinite(s_v) ? s_v * (nu_model - identifier_.inventory_deviation()) : Scalar(0);
    const Scalar e = (t.z_v - bias_v) - placement_v;
    if (!std::isfinite(e)) return false;
    return averaged_ratio(placed_mean_v_, e, window_start, t.dt_s) > Scalar(1);
  }

  // The consistency check on the fusion (Config::innovation_rejects): true when this tick's
  // averaged regression innovation fails the gate. The mean restarts at each learning window.
  bool fusion_rejected(const FilmTick<Scalar>& t, Scalar s_v, Scalar nu_model, Scalar bias_v, bool window_start) {
    if (!c_.innovation_rejects || !(c_.innovation_sd_v > Scalar(0))) return false;
    const Scalar e = identifier_.innovation_v(t.u_ohm_m2, t.z_v, t.r.markov_v_per_ohm_m2, s_v, nu_model, bias_v);
    if (!std::isfinite(e)) return false;  // learn() rejects it and says why
    return averaged_ratio(fusion_mean_v_, e, window_start, t.dt_s) > Scalar(1);
  }

  // The table's start condition (Config::bias_table_start_margin) at the stoichiometry where a
  // charge's learning opens; a NaN stoichiometry (no table needs it) passes.
  bool table_starts_at(Scalar x_neg) const {
    const auto& t = c_.model_bias_table.nominal();
    if (!t.on() || std::isnan(x_neg)) return true;
    return !(x_neg > t.x_first + c_.bias_table_start_margin * (t.x_last - t.x_first));
  }

  // The charge's stop condition (Config::misfit_stop_s). A charge tests the fit it starts with
  // (the model placed at its inventory): past the limit of failed placed-residual tests that fit
  // did not explain the charge, and the fit goes back to the last one that did (verified_fit_;
  // the prior before any), once per charge. A charge that passes verifies its starting fit.
  // Start condition: the starting fit is settled, or a stop has fired before. A fit still at (or
  // restarted from) the prior is not yet placed at the cell's inventory, and the placed test's
  // linear correction misses a charge's ends there (an LCO truth 0.8 % rich: 3 mV at the start,
  // 8-19 mV at the end): tested, a cell whose inventory is off would be put back at every charge.
  // Once a stop has fired the cell is one the model may not describe (About:Energy's spread set:
  // the first charge from the prior runs away), and every later charge is tested.
  void misfit_stop(bool start, bool misfit, Scalar dt_s) {
    if (start) {
      if (misfit_armed_ && !misfit_stopped_) verified_fit_ = fit_at_charge_;
      misfit_in_charge_s_ = Scalar(0);
      misfit_stopped_ = false;
      fit_at_charge_ = identifier_.fit();
      if (inventory_implausible()) {
        stop_charge();
        implausible_ = true;
      }
      misfit_stopped_ = misfit_stopped_ || implausible_;
      misfit_armed_ = (c_.misfit_stop_s > Scalar(0) || c_.stated_inventory_sd > Scalar(0)) &&
                      (misfit_seen_ || identifier_.settled());
    }
    if (!misfit_armed_ || misfit_stopped_ || !misfit) return;
    misfit_in_charge_s_ += dt_s;
    if (misfit_in_charge_s_ > c_.misfit_stop_s) stop_charge();
  }
  // The fit put back is the one reported: a hold (hold_reported) kept the values of the fit that
  // failed, and the put-back fit may never settle again to release it.
  void stop_charge() {
    identifier_.restore_fit(verified_fit_);
    holding_ = false;
    misfit_stopped_ = true;
    misfit_seen_ = true;
  }
  // Config::stated_inventory_sd's plausibility test of the fitted inventory.
  bool inventory_implausible() const {
    const Scalar sd = c_.stated_inventory_sd, nu = identifier_.theta()(2);
    return sd > Scalar(0) && std::isfinite(nu) && std::fabs(nu) > kInventoryGateSd * sd;
  }

  // The stop condition of the design-time calibration (ModelBiasTable::x_trusted_last): the model's
  // mean anode stoichiometry past the span where it fits the nominal cell; latched to the charge's end.
  bool beyond_trusted_span(Scalar x_neg) {
    const Scalar x_last = c_.model_bias_table.trusted_last(bias_nu_);
    if (!std::isfinite(x_last)) return false;
    if (stopped_in_charge_) return true;
    stopped_in_charge_ = x_neg > x_last;  // NaN: no stoichiometry, no stop
    return stopped_in_charge_;
  }

  // The stated spread's film equivalent at this learning tick: the model's voltage 1-sigma for it
  // over the film's sensitivity H (as the temperature sensor's term).
  template <class Model>
  void update_spread(const Model& model, const ModelTickResult<Scalar>& r) {
    if constexpr (kGivesSpread<Model, Scalar>) {
      if (!c_.spread.any()) return;
      const Scalar per = model.spread_voltage_sd_v(r.current_a, r.voltage_v, c_.spread) / r.markov_v_per_ohm_m2;
      if (std::isfinite(per)) film_spread_ohm_m2_ = std::fabs(per);
    } else {
      (void)model;
      (void)r;
    }
  }

  // The voltage sensor's stated offset 1-sigma over the film's sensitivity H at this learning tick.
  void update_voltage_offset_term(Scalar markov_v_per_ohm_m2) {
    if (!(c_.voltage_offset_sd_v > Scalar(0))) return;
    const Scalar per = c_.voltage_offset_sd_v / markov_v_per_ohm_m2;
    if (std::isfinite(per)) film_voltage_offset_ohm_m2_ = std::fabs(per);
  }

  // The open-circuit capacity of the identified inventory (less the model's own lithium loss)
  // times the identified area scale, at the first tick, every kCapacityEveryTicks learning ticks and when a learning window
  // closes: two bisections, not every tick.
  template <class Model>
  void update_capacity(const Model& model, bool identifying, Scalar nominal_inventory_mol, Scalar area_scale,
                       Scalar area_inventory_mol) {
    const bool window_closed = identifying_ && !identifying;
    identifying_ = identifying;
    capacity_ticks_ = identifying ? capacity_ticks_ + 1u : 0u;
    const bool due = window_closed || capacity_ticks_ >= kCapacityEveryTicks;
    if constexpr (kGivesCapacity<Model, Scalar>) {
      if (!(due || std::isnan(capacity_ah_)) || !(nominal_inventory_mol > Scalar(0))) return;
      capacity_ticks_ = 0u;
      const Scalar n0 = nominal_inventory_mol;
      const Scalar before_loss = std::isfinite(area_inventory_mol) ? area_inventory_mol
                                                                   : n0 * (Scalar(1) + reported().inventory_deviation());
      const Scalar n = before_loss - model.li_loss_mol();
      // The model's inventory is in the nominal electrodes' units (n / a: AreaScale), the
      // capacity in the cell's: a C_nom(n / a). Once a span has measured a, n is the model's
      // inventory at that span (consistent with a: AreaScale's header), else the identified one.
      capacity_ah_ = area_scale * Model::open_circuit_capacity_ah(n);
      // The capacity moves with the inventory nearly one to one near the nominal cell (0.98:
      // tests/firmware/test_temperature.cpp): its relative sd is the inventory's.
      capacity_sd_ah_ = capacity_ah_ * reported().inventory_sd() * n0 / n;
      if (c_.current_gain_sd > Scalar(0)) {
        const Scalar gain_sd_ah = capacity_ah_ * c_.current_gain_sd;
        capacity_sd_ah_ = std::sqrt(capacity_sd_ah_ * capacity_sd_ah_ + gain_sd_ah * gain_sd_ah);
      }
    }
  }

  // Relative inventory probe for S = dV/dnu: large enough for float, small against the 1 %
  // deviations a cell has.
  static constexpr Scalar kInventoryProbe = Scalar(1e-3);
  static constexpr Scalar kInventoryGateSd = Scalar(3);  // Config::stated_inventory_sd's gate, in its sds
  static constexpr Scalar kTemperatureProbeK = Scalar(1);
  static constexpr StatusWord kIdentifierRejectMask =
      bit(FwStatus::kRejectedNonFinite) | bit(FwStatus::kThetaRestored) | bit(FwStatus::kConfigInvalid);
  static constexpr std::uint32_t kCapacityEveryTicks = 1500u;  // 5 minutes at 0.2 s

  Config c_;
  Identifier identifier_;
  Identifier held_;       // reported while holding_ (Config::hold_until_settled)
  bool holding_ = false;
  bool held_is_prior_ = true;  // held_ is the prior (never fitted): no spread term on its sd
  bool restarted_charge_ = false;      // held through the charge the restart learns in (Config)
  bool learned_since_restart_ = false;  // the restarted identifier learned in a CC charge
  Scalar capacity_ah_ = std::numeric_limits<Scalar>::quiet_NaN();
  Scalar capacity_sd_ah_ = std::numeric_limits<Scalar>::quiet_NaN();
  Scalar innovation_mean_v_ = Scalar(0);
  Scalar innovation_ratio_ = Scalar(0);
  Scalar fusion_mean_v_ = Scalar(0);  // the regression innovation's mean (fusion_rejected)
  Scalar placed_mean_v_ = Scalar(0);  // the placed residual's mean (placed_test_fails)
  Scalar bias_nu_ = Scalar(0);        // the model's inventory deviation the bias levels are read at
  bool stopped_in_charge_ = false;    // this charge's learning stopped (beyond_trusted_span)
  bool table_in_charge_ = true;       // this charge met the table's start condition
  bool covered_charge_ = true;        // the calibration covers this charge (ModelBiasTables::covers)
  bool misfit_stopped_ = false;       // this charge's fusion stopped (misfit_stop)
  bool misfit_armed_ = false;         // this charge is tested (misfit_stop's start condition)
  bool misfit_seen_ = false;          // a stop has fired since power-up (misfit_stop)
  bool implausible_ = false;          // a charge's fit left the stated inventory tolerance (misfit_stop)
  Scalar misfit_in_charge_s_ = Scalar(0);
  typename Identifier::RlsState fit_at_charge_{};  // the fit at this charge's first learning tick
  typename Identifier::RlsState verified_fit_{};   // the last fit a charge's test passed (the prior before any)
  bool identifying_ = false;
  Scalar v_warm_v_ = Scalar(0);                // this tick's voltage at +kTemperatureProbeK
  Scalar film_per_kelvin_ohm_m2_ = Scalar(0);  // |dV/dT / H| of the last learning tick
  Scalar film_spread_ohm_m2_ = Scalar(0);      // the stated spread's film 1-sigma, last learning tick
  Scalar film_voltage_offset_ohm_m2_ = Scalar(0);  // the voltage sensor's stated offset as a film, last learning tick
  std::uint32_t capacity_ticks_ = 0u;          // learning ticks since the capacity was last computed
};

}  // namespace bms::fw
