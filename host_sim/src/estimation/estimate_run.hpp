#pragma once
// Runs the firmware's tick (bms::fw::BmsCore, the same code as on target) offline over a data
// file, with either the firmware's reduced model or the full truth DFN as the main model,
// and scores the film-resistance estimate against the truth when the file carries it.
#include <cmath>
#include <cstdint>
#include <functional>
#include <string>
#include <vector>

#include "io/measured_profile.hpp"

#include "bms/fw/cell_effects.hpp"
#include "bms/fw/operating_mode.hpp"
#include "cell/cell_parameters.hpp"
#include "sim/cycler.hpp"

namespace bms {

struct EstimateData {
  std::vector<double> t_s, current_a, voltage_v;  // measured (what the firmware sees)
  std::vector<double> temperature_k;              // measured (temperature_meas_k); empty: none
  std::vector<int> cycle;                         // from the file, or 1
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
// The coarsest sample step the estimator accepts (s): beyond it the firmware sees too few
// samples per constant-current charge to learn from (measured in docs/results/reliability.md).
constexpr double kMaxSampleStepS = 60.0;

// The tick the model runs at: EstimateData::tick_s when set, else fixed_tick_s().
double model_tick_s(const EstimateData& d);

// The fixed tick the firmware model runs the data at: the median sample step rounded to
// 1 ns. Throws InputError when any step is more than 1 % off the median.
double fixed_tick_s(const EstimateData& d);

struct EstimateOptions {
  std::string model = "reduced";  // reduced | full
  std::string settings = "best";  // best | paper (apply_settings) | custom (the flags as given)
  bool learning = true;           // false: the control run, every RCSI / RLS update off
  bool identify_growth = false;   // the best profile's FilmGrowthIdentifier instead of ARX RCSI
  bool learn_inventory = true;    // with identify_growth: the inventory is the third parameter
  double model_bias_ohm = -1.0;   // with identify_growth: < 0 = the main model's calibrated bias
  double relinearise_inventory = 1e-3;
  std::vector<double> theta0;     // paper profile: RCSI's theta(0), 2 n_c values; empty = [1, 0, ..] (hold)  // with identify_growth: BmsCore::Config::relinearise_inventory
  int nc = 1;                     // subsystem order, 1..8
  double p0 = 5e-7;
  double p0_y0 = -1.0;  // < 0: same as p0 (the paper's P(0) = p0 I)
  double lambda = 1.0;
  double eta = 0.0;
  double h_v_per_ohm_m2 = 0.01;
  bool markov_from_model = false;
  double r_film_init_ohm_m2 = -1.0;  // < 0: the cell's initial film resistance
  InitialConditions ic;              // of the model (not the truth)
  bool resync = false;               // state re-synchronisation at the end of each CV phase
  bool resync_at_start = true;      // with --resync: also at the first sample (power-up from rest)
  double resync_current_a = 0.25;
  unsigned resync_window_ticks = 1;  // ticks of measurement each resync fits a line to
  double nominal_inventory_mol = 0.0;  // set by run_estimate from the cell's nominal state
  double inventory_error_pct = 0.0;    // with resync: the inventory it assumes is off nominal by this
  double warmup_s = 0.0;             // RCSI learns only after this long in each CC charge
  bool calibrate_bias = false;       // first CC charge = reference charge at the initial film resistance
  unsigned reference_after_resyncs = 1;  // with --resync: resyncs before the reference charge
  bool average_estimate = false;     // report the mean of u_hat over each charge's learning window
  bool propagate_growth = false;     // the reported estimate follows the model's predicted film growth
  double growth_scale = 1.0;         // with propagate_growth: factor on the growth law (robustness studies)
  // Effects added to the main model (bms/fw/cell_effects.hpp), e.g. the one `bmssim diagnose`
  // found; none by default. nominal_capacity_ah is taken from the cell.
  fw::EffectParameters<double> model_effects;
  bool model_effects_on = false;
  DfnMesh mesh;                      // full model only
  double rtol = 1e-6;                // full model only
};

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
};

// Sets one main-model effect from "NAME=VALUE" (contract names: contact_resistance [ohm],
// hysteresis [V, half the branch gap], current_offset [A], current_gain [relative]).
// Throws InputError naming the option and the field for anything else.
void add_model_effect(EstimateOptions& o, const std::string& spec);

// `--beyond-paper`: the firmware's best settings, read from BmsCore::beyond_paper_config (one
// source for the firmware and this tool). `given(flag)` says whether the user set that flag
// explicitly; such a value is kept, so `--beyond-paper --resync-window 1` is an ablation.
void apply_beyond_paper(EstimateOptions& o, const std::function<bool(const char* flag)>& given);

// `--settings best|paper`: the named profiles (BmsCore::best_config, the paper's RCSI); explicit
// flags win as with apply_beyond_paper. Throws InputError for another name.
void apply_settings(EstimateOptions& o, const std::function<bool(const char* flag)>& given);

// growth_err_pct of the contract: |(R_est - R_est,ref) - (R_true - R_true,ref)| / |R_true - R_true,ref|
// x 100, ref = the end of the first CC charge with learning, compared at the end of the last.
double growth_error_pct(const std::vector<EstimateRow>& rows);

using EstimateProgress = std::function<void(std::size_t row, std::size_t rows)>;

EstimateResult run_estimate(const EstimateData& data, const CellParameters& cell, const EstimateOptions& o,
                            const EstimateProgress& progress = {});

// Median and end-of-phase relative errors per cycle over the rows in CC charge (the detected
// mode, and the true mode when known).
std::vector<CycleScore> score_cycles(const std::vector<EstimateRow>& rows, bool use_true_mode,
                                     const std::vector<fw::Mode>& true_mode);

}  // namespace bms
