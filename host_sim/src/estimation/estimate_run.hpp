#pragma once
// Runs the firmware's tick (bms::fw::BmsCore, the same code as on target) offline over a data
// file, with either the firmware's reduced model or the full truth DFN as the main model,
// and scores the film-resistance estimate against the truth when the file carries it.
#include <cmath>
#include <type_traits>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "io/measured_profile.hpp"

#include "bms/fw/model/cell_effects.hpp"
#include "bms/fw/config/make_config.hpp"
#include "bms/fw/estimation/operating_mode.hpp"
#include "cell/cell_parameters.hpp"
#include "sim/cycler.hpp"

namespace bms {

struct EstimateData {
  std::vector<double> t_s, current_a, voltage_v;  // measured (what the firmware sees)
  std::vector<double> temperature_k;              // measured (temperature_meas_k); empty: none
  std::vector<int> cycle;                         // from the file, or 1
  std::vector<double> step_time_s;  // a cycler file's time since its step began (NaN: not logged); empty: none
  std::vector<double> r_film_true_ohm_m2;         // empty when the file has no truth
  std::vector<fw::Mode> true_mode;                // empty when the file has no mode column
  // Truth mean stoichiometries (scoring the inventory estimate only); empty when absent.
  std::vector<double> stoich_neg_true, stoich_pos_true;
  std::vector<double> capacity_true_ah;  // the truth's open-circuit capacity (scoring); empty when absent
  std::string source;
  std::string layout_note;  // a measured file: how it was read and sampled
  // A measured file: the model's tick (s), at most the median sample step and kMaxModelTickS; each
  // sample is one firmware tick, the ticks between two samples are missed ticks the firmware
  // catches up on. 0: the data are evenly sampled and run at that step (truth.csv).
  double tick_s = 0.0;
  double median_step_s = 0.0;  // a measured file's median sample step
  bool has_truth() const { return !r_film_true_ohm_m2.empty(); }
};

// Reads truth.csv (current_meas_a, voltage_meas_v; truth columns only for scoring), or a
// measured file (About:Energy or any cycler CSV with time, current and voltage columns picked
// by name; no truth): the latter is kept as sampled (memory grows with its samples only) and
// run with a model tick of at most kMaxModelTickS: a sample per firmware tick, the model
// stepped over the ticks between samples by the firmware's catch-up of missed ticks.
EstimateData read_estimate_data(const std::string& file, CurrentSign sign = CurrentSign::by_layout);

// The longest model tick a measured record is run at (s): the reduced model's implicit step
// and the mode detector are accurate at 1 s; a coarser record is stepped at this tick between
// its samples.
constexpr double kMaxModelTickS = 1.0;
// The coarsest sample step the estimator accepts (s). Measured (docs/results/reliability.md,
// section 9): on 2- and 5-cycle records of the paper cell, 1-2 s samples give the film within
// 2 % of the truth; 3-60 s samples scatter it by -12 % to +26 % (the growth gain, told apart from
// the level only across charges, is what coarser records leave undetermined). A coarser record is
// refused naming this interval rather than estimated wrong.
constexpr double kMaxSampleStepS = 2.0;
// A gap over this (s) is a power cycle (the firmware profiles' power_cycle_after_s): a charge's
// count ends at it.
constexpr double kPowerCycleGapS = fw::kPowerCycleGapS;
// The coarsest sample step a measured record is read and run at (s): a control run
// (--no-learning: the nominal model and the charges' counted capacity, no film identified) may
// use records up to this step; learning needs kMaxSampleStepS.
constexpr double kMaxControlSampleStepS = 60.0;

// Refuses (InputError naming the file and the interval) a record too coarse for what is asked:
// learning needs a sample every kMaxSampleStepS.
void require_sampling_for_learning(const EstimateData& d, bool learning);

// The tick the model runs at: EstimateData::tick_s when set, else fixed_tick_s().
double model_tick_s(const EstimateData& d);

// The fixed tick the firmware model runs the data at: the median sample step rounded to
// 1 ns. Throws InputError when any step is more than 1 % off the median.
double fixed_tick_s(const EstimateData& d);

// What `bmssim estimate` runs: the main model, an estimator profile of the nominal cell and
// the typed overrides the user gave (bms/fw/config/make_config.hpp: one the profile does not use is
// refused, exit 2 naming it).
struct EstimateOptions {
  std::string model = "reduced";  // reduced | full
  fw::Profile profile = fw::Profile::best;
  fw::Overrides overrides;
  // With the observer or the best profile: the nominal lithium inventory the estimator assumes is
  // off the cell's by this percent (how well a BMS must know its cell's inventory).
  fw::Given<double> inventory_error_pct;
  InitialConditions ic;              // of the model (not the truth)
  // Effects added to the main model (bms/fw/model/cell_effects.hpp), e.g. the one `bmssim diagnose`
  // found; none by default. nominal_capacity_ah is taken from the cell.
  fw::EffectParameters<double> model_effects;
  bool model_effects_on = false;
  // The reduced model's design-time bias of a cell other than the paper's, used when
  // model_bias_ohm < 0 (estimation/design_bias.hpp: a converged DFN of the nominal cell; it may
  // be negative, so it has its own field); NaN = not computed.
  double design_bias_ohm = std::nan("");
  // Its state-of-charge-dependent part (the same calibration; bms/fw/model/model_bias_table.hpp),
  // added to the constant; off (the default, and the paper cell): the constant alone.
  fw::ModelBiasTables<double> design_bias_table{};
  DfnMesh mesh;                      // full model only
  bool points_given = false;         // --points (full model only)
  double rtol = 1e-6;                // full model only
};

// The effective configuration a run used (written to summary.json's "options").
struct EstimateConfigSummary {
  bool filled = false;
  int nc = 1;
  double h_v_per_ohm_m2 = 0, p0_u = 0, p0_y0 = 0, lambda = 0, eta = 0;
  bool h_from_model = false, resync_at_cv_end = false, resync_at_start = false;
  unsigned resync_window_ticks = 0, reference_after_resyncs = 0;
  double resync_settle_s = 0.0;
  double resync_current_a = 0, warmup_s = 0, nominal_inventory_mol = 0, voltage_min_v = 0, voltage_max_v = 0, dt_s = 0;
  bool calibrate_bias = false, average_estimate = false, learning = true, identify_growth = false, learn_inventory = true;
  double propagated_growth_ohm_m2_per_a_m3_s = 0, model_bias_ohm = 0, relinearise_inventory = 0;
  fw::StatedSpread<double> spread{};  // the cell's stated parameter spread (relative 1-sigma)
  bool fuse_level_only = false;       // with a spread: the prior combined with the fitted level alone
  double film_initial_sd_rel = 0;     // the initial film's stated tolerance (relative 1-sigma; 0: none)
  fw::ModelBiasTables<double> model_bias_table{};  // the bias's state-of-charge and inventory part (off: none)
  double voltage_offset_sd_v = 0;     // the voltage sensor's stated offset accuracy (1-sigma)
  double current_gain_sd = 0;         // the current sensor's stated gain accuracy (relative 1-sigma)
  bool voltage_offset = false;        // the voltage sensor's offset measured and removed
};

template <class Config>
EstimateConfigSummary summarise_config(const Config& c, int nc) {
  EstimateConfigSummary s;
  s.filled = true;
  s.nc = nc;
  s.resync_at_cv_end = c.resync_at_cv_end;
  s.resync_at_start = c.resync_at_start;
  s.resync_window_ticks = c.resync_window_ticks;
  s.resync_settle_s = static_cast<double>(c.resync_settle_s);
  s.resync_current_a = c.resync_current_a;
  s.warmup_s = c.rcsi_warmup_s;
  s.nominal_inventory_mol = c.nominal_inventory_mol;
  s.voltage_min_v = c.voltage_min_v;
  s.voltage_max_v = c.voltage_max_v;
  s.dt_s = c.dt_s;
  s.learning = c.learning;
  s.voltage_offset = c.voltage_offset;
  const auto& p = c.film_path;
  if constexpr (std::decay_t<decltype(p)>::kKind == fw::FilmPathKind::rcsi) {
    s.h_v_per_ohm_m2 = p.estimator.markov_v_per_ohm_m2;
    s.p0_u = p.estimator.p0_u;
    s.p0_y0 = p.estimator.p0_y0;
    s.lambda = p.estimator.lambda;
    s.eta = p.estimator.eta;
    s.h_from_model = p.markov_from_model;
    s.reference_after_resyncs = p.reference_after_resyncs;
    s.calibrate_bias = p.calibrate_bias;
    s.average_estimate = p.average_estimate;
    s.propagated_growth_ohm_m2_per_a_m3_s = p.nominal_growth_ohm_m2_per_a_m3_s;
  } else {
    s.identify_growth = true;
    s.h_from_model = true;  // the identifier takes H = dV/dR_film from the model at every learning tick
    s.learn_inventory = p.identifier.learn_inventory;
    s.model_bias_ohm = p.model_bias_ohm;
    s.model_bias_table = p.model_bias_table.template as<double>();
    s.relinearise_inventory = p.relinearise_inventory;
    s.spread = {double(p.spread.anode_i0_rel), double(p.spread.cathode_i0_rel), double(p.spread.transport_rel),
                double(p.spread.area_rel)};
    s.fuse_level_only = p.fuse_level_only;
    s.film_initial_sd_rel = double(p.identifier.stated_film_initial_sd_rel);
    s.voltage_offset_sd_v = double(p.voltage_offset_sd_v);
    s.current_gain_sd = double(p.current_gain_sd);
  }
  return s;
}

struct EstimateRow {
  double t_s;
  int cycle;
  fw::Mode mode;
  bool rcsi_active;
  double r_film_est_ohm_m2, r_film_true_ohm_m2, z_v, model_voltage_v, model_current_a, j_side_a_m3,
      li_loss_ah;
  double film_initial_ohm_m2, growth_gain, inventory_deviation;  // identified (best profile)
  double markov_v_per_ohm_m2, inventory_sensitivity_v, growth_ohm_m2;  // H, S, G (the bound)
  double inventory_err_pct;  // estimated vs true cyclable lithium, NaN without truth stoichiometries
  // The identifier's 1-sigma of the film, the open-circuit capacity and its 1-sigma (NaN without
  // the identifier), the truth's capacity (NaN without), the innovation test ratio (> 1: misfit).
  double r_film_sd_ohm_m2, capacity_est_ah, capacity_sd_ah, capacity_true_ah, innovation_test_ratio;
  double current_offset_a;  // the current sensor offset the firmware subtracts (CurrentOffset)
  // The main model's mean anode stoichiometry after the tick (NaN where the model gives none) and
  // the design-time bias the identifier subtracts from z at it [V] (NaN without the identifier).
  double model_stoich_neg, model_bias_v;
  double voltage_offset_v;  // the voltage sensor offset the firmware subtracts (VoltageOffset)
  double area_scale;        // the electrode-capacity scale the firmware identified (AreaScale)
  std::uint32_t status;
};

struct CycleScore {
  int cycle;
  std::size_t cc_charge_ticks;
  double r_film_err_median_pct, r_film_err_end_pct, r_film_true_end_ohm_m2, r_film_est_end_ohm_m2;
  double inventory_err_end_pct;  // at the cycle's last CC-charge tick; NaN without truth
  double capacity_err_pct;       // (estimate - truth) / truth at the cycle's last CC-charge tick; NaN without
  double film_within_2sd_pct;    // share of the scored CC-charge ticks with |error| <= 2 sd; NaN without sd
  double misfit_pct;             // share of the cycle's learning ticks whose innovation test failed
};

struct EstimateResult {
  std::vector<EstimateRow> rows;
  std::vector<std::vector<double>> theta_rows;  // per row, 2 nc values
  std::vector<CycleScore> cycles;
  std::vector<double> theta;  // final
  double growth_err_pct = std::nan("");  // contract: growth tracked from the first learning charge's end
  double wall_s = 0.0;
  std::uint32_t status = 0;   // OR of all tick status words
  std::size_t newton_cap_hits = 0;
  std::size_t samples_skipped = 0;  // measured samples less than half a model tick after the previous
  EstimateConfigSummary config;  // what ran
  double model_bias_ohm = std::nan("");  // the design-time bias the reduced model ran with
};

// Sets one main-model effect from "NAME=VALUE" (contract names: contact_resistance [ohm],
// hysteresis [V, half the branch gap], current_offset [A], current_gain [relative]).
// Throws InputError naming the option and the field for anything else.
void add_model_effect(EstimateOptions& o, const std::string& spec);

// A cell file's own contact resistance and hysteresis (BPX User-defined keys, e.g. from
// `diagnose --write-cell`) as model effects of the reduced model, except those the user named
// with --model-effect (`given`: their NAME=VALUE specs). The full model has them already.
void adopt_cell_effects(EstimateOptions& o, const CellParameters& cell, const std::vector<std::string>& given = {});

// Throws InputError naming the option for an override the profile does not use, or a value out
// of range; cheap, so callers run it before any long work.
void check_estimate_options(const EstimateOptions& o);

// The nominal cell the estimator may know (the information rule): the cell's design inventory
// (off by --inventory-error-pct), initial film, Ramadass constant and voltage window, and the
// main model's design-time bias (the reduced model's calibration; 0 for the full DFN).
fw::NominalCell estimate_nominal_cell(const CellParameters& cell, const EstimateOptions& o);

// The overrides run_estimate hands make_config: the user's, and the observer off for the full
// model (it has none).
fw::Overrides estimate_overrides(const EstimateOptions& o);

// The configuration run_estimate runs the core with: make_config over estimate_nominal_cell with
// estimate_overrides, at the data's tick. A refused override leaves cfg as it was.
template <class Core>
fw::Refusal estimate_config(const CellParameters& cell, const EstimateOptions& o, double dt_s,
                            typename Core::Config& cfg) {
  const fw::Refusal r = fw::make_config<Core>(estimate_nominal_cell(cell, o), o.profile, estimate_overrides(o), cfg);
  if (r.option == nullptr) cfg.dt_s = dt_s;
  return r;
}

// The rows growth_err_pct compares: ref = the end of the first CC charge with learning (the
// first CC charge's end in a run that never learned), last = the end of the last CC charge; each
// a row with a finite true film. valid = false: fewer than two such ends.
struct GrowthSpan {
  std::size_t ref = 0, last = 0;
  bool valid = false;
};
GrowthSpan growth_span(const std::vector<EstimateRow>& rows);

// growth_err_pct of the contract: |(R_est - R_est,ref) - (R_true - R_true,ref)| / |R_true - R_true,ref|
// x 100 over growth_span (NaN where it is not valid or the truth did not grow).
double growth_error_pct(const std::vector<EstimateRow>& rows);

using EstimateProgress = std::function<void(std::size_t row, std::size_t rows)>;

EstimateResult run_estimate(const EstimateData& data, const CellParameters& cell, const EstimateOptions& o,
                            const EstimateProgress& progress = {});

// The measurement stream the firmware ticks on in run_estimate, as the board's replay of a record
// reads it (target/m4f_blind_main.cpp, format BMSMEAS3, little-endian): "BMSMEAS3", uint32 sample
// count, uint32 0; the doubles model tick [s], the record's sample step when coarser than the
// tick [s] (else 0), learning (1 or 0); then per sample that reaches the tick the doubles
// voltage [V], current [A, discharge positive], temperature [K, 0: none] and the ticks missed
// before it (the core's ticks_missed).
std::string firmware_stream(const EstimateData& d, bool learning);

// Median and end-of-phase relative errors per cycle over the rows in CC charge (the detected
// mode, and the true mode when known).
std::vector<CycleScore> score_cycles(const std::vector<EstimateRow>& rows, bool use_true_mode,
                                     const std::vector<fw::Mode>& true_mode);

}  // namespace bms
