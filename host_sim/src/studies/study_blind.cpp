#include "studies/study_blind.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <map>
#include <mutex>
#include <random>
#include <sstream>
#include <thread>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "baselines/baseline_run.hpp"
#include "cell/reduced_cell_record.hpp"
#include "estimation/design_bias.hpp"
#include "estimation/estimate_output.hpp"
#include "estimation/estimate_run.hpp"
#include "estimation/film_bound.hpp"
#include "io/gnuplot.hpp"
#include "io/input_error.hpp"
#include "io/shell_word.hpp"
#include "io/statistics.hpp"
#include "io/text_file.hpp"
#include "sim/cell_catalog.hpp"
#include "sim/simulation_plan.hpp"
#include "sim/truth_output.hpp"
#include "studies/study_report.hpp"

namespace bms::study {

namespace {

namespace fs = std::filesystem;
using nlohmann::json;

// ---- the truths --------------------------------------------------------------------------

struct TruthDraw {
  int set = 1, seed = 1;
  double r0_scale = 1, growth_scale = 1, i0_scale = 1, inventory_scale = 1;
  double conductivity_scale = 1, diffusivity_neg = 1, diffusivity_pos = 1;
  double temperature_k = 298.15;  // set 3: ambient (and, self-heating, initial) temperature
  bool self_heating = false;      // set 3: the lumped thermal model at kSelfHeatingWPerK
  // Set 4, cell-to-cell spread: electrolyte diffusivity, both electrodes' exchange currents, the
  // cathode's particle-size spread (log-normal sigma; 0 = one size), the electrode area (capacity).
  double electrolyte_diffusivity = 1, i0_neg = 1, i0_pos = 1, particle_size_sigma = 0, area_scale = 1;
  // Set 5, the sensors of a BMS front end: offsets and gain, the temperature sensor's noise.
  double current_offset_a = 0, current_gain = 0, voltage_offset_v = 0, temperature_offset_k = 0, noise_t_k = 0;
  // Set 6: the cycle as an experiment written as PyBaMM writes one ("" = cccv).
  std::string protocol;

  // The film's growth rate relative to the nominal law: the law's factor times the side current's.
  double true_gain() const { return growth_scale * i0_scale; }

  std::vector<std::string> set_args(const CellParameters& nominal) const {
    std::vector<std::string> a = {
        fmt::format("r_film_initial_ohm_m2={}", r0_scale * nominal.side.initial_film_resistance_ohm_m2),
        fmt::format("film_growth_scale={}", growth_scale), fmt::format("side_i0_scale={}", i0_scale),
        fmt::format("inventory_scale={}", inventory_scale)};
    if (set == 3) a.push_back(fmt::format("temperature_k={}", temperature_k));
    if (set == 2 || set == 4) {
      a.push_back(fmt::format("conductivity_scale={}", conductivity_scale));
      a.push_back(fmt::format("diffusivity_scale_negative={}", diffusivity_neg));
      a.push_back(fmt::format("diffusivity_scale_positive={}", diffusivity_pos));
    }
    if (set == 4) {
      a.push_back(fmt::format("electrolyte_diffusivity_scale={}", electrolyte_diffusivity));
      a.push_back(fmt::format("i0_scale_negative={}", i0_neg));
      a.push_back(fmt::format("i0_scale_positive={}", i0_pos));
      a.push_back(fmt::format("electrode_area_scale={}", area_scale));
    }
    return a;
  }

  std::vector<std::string> effect_args() const;
};

// Set 3's self-heating truths: the lumped thermal model's heat-transfer coefficient (an 18650-size
// cell in still air; 298-302 K over a cycle at 25 C).
constexpr double kSelfHeatingWPerK = 0.05;

std::vector<std::string> TruthDraw::effect_args() const {
  std::vector<std::string> e;
  if (self_heating) e.push_back(fmt::format("thermal={}", kSelfHeatingWPerK));
  if (particle_size_sigma > 0.0) e.push_back(fmt::format("particle_size={}", particle_size_sigma));
  if (set == 5) {
    e.push_back(fmt::format("current_offset={}", current_offset_a));
    e.push_back(fmt::format("current_gain={}", current_gain));
    e.push_back(fmt::format("voltage_offset={}", voltage_offset_v));
    e.push_back(fmt::format("temperature_offset={}", temperature_offset_k));
  }
  return e;
}

// Set 6's cycle: a partial discharge to a drawn state of charge, a rest, a CC charge at a drawn
// rate from there, the CV hold, a second rest. Rests log-uniform (minutes to hours).
template <class Uniform>
std::string draw_protocol(Uniform& u, const CellParameters& nominal) {
  const double discharge_c = u(0.5, 1.0);
  const double depth = u(0.2, 0.9);  // of the nominal capacity: the charge starts from 10-80 % SoC
  const double discharge_min = std::round(depth * 60.0 / discharge_c);
  const double rest1_min = std::round(std::exp(u(std::log(5.0), std::log(120.0))));
  const double charge_c = u(0.3, 1.0);
  const double rest2_min = std::round(std::exp(u(std::log(2.0), std::log(60.0))));
  return fmt::format(
      "Discharge at {:.2f}C for {:g} minutes or until {:g} V; Rest for {:g} minutes; Charge at {:.2f}C until {:g} V; "
      "Hold at {:g} V until 125 mA; Rest for {:g} minutes",
      discharge_c, discharge_min, nominal.lower_voltage_v, rest1_min, charge_c, nominal.upper_voltage_v,
      nominal.upper_voltage_v, rest2_min);
}

// Uniform draws from the ranges; the estimator sees none of them. Sets 1-3 draw exactly
// as before (the later sets' draws come after theirs, in sets of their own).
TruthDraw draw_truth(int set, int seed, const CellParameters& nominal) {
  std::mt19937_64 rng(0xB11DULL * 1000003ULL + static_cast<unsigned long long>(set) * 10007ULL +
                      static_cast<unsigned long long>(seed));
  auto u = [&rng](double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng); };
  TruthDraw d;
  d.set = set;
  d.seed = seed;
  d.r0_scale = u(0.8, 1.2);
  d.growth_scale = u(0.3, 3.0);
  d.i0_scale = u(0.5, 2.0);
  d.inventory_scale = u(0.99, 1.01);
  if (set == 2) {
    d.conductivity_scale = u(0.9, 1.1);
    d.diffusivity_neg = u(0.8, 1.2);
    d.diffusivity_pos = u(0.8, 1.2);
  }
  if (set == 3) {
    // The operating envelope: 5-45 C; every third truth heats itself (it moves within each charge).
    d.temperature_k = u(278.15, 318.15);
    d.self_heating = seed % 3 == 0;
  }
  if (set == 4) {
    // Cell-to-cell spread: transport +-20 %, kinetics +-30 %, particle sizes, capacity +-3 %.
    d.conductivity_scale = u(0.8, 1.2);
    d.electrolyte_diffusivity = u(0.8, 1.2);
    d.diffusivity_neg = u(0.8, 1.2);
    d.diffusivity_pos = u(0.8, 1.2);
    d.i0_neg = u(0.7, 1.3);
    d.i0_pos = u(0.7, 1.3);
    d.particle_size_sigma = u(0.05, 0.3);
    d.area_scale = u(0.97, 1.03);
  }
  if (set == 5) {
    // A BMS front end: current offset +-10 mA and gain +-0.5 %, voltage offset +-0.5 mV, a
    // temperature sensor 0.5 K off (either way) with 0.2 K noise; with both noises (kSensorNoise).
    d.current_offset_a = u(-0.010, 0.010);
    d.current_gain = u(-0.005, 0.005);
    d.voltage_offset_v = u(-0.5e-3, 0.5e-3);
    d.temperature_offset_k = u(0.0, 1.0) < 0.5 ? -0.5 : 0.5;
    d.noise_t_k = 0.2;
  }
  if (set == 6) d.protocol = draw_protocol(u, nominal);
  return d;
}

// The cell a study's truths are drawn around, and what the estimator may know of it: the nominal
// parameters and, for a cell other than the paper's, the design-time bias of the firmware's model
// (computed once from the nominal cell, as `estimate --cell X` computes it at start).
struct StudyCell {
  std::string arg = "paper";  // as --cell names it
  CellParameters nominal;
  DesignBias bias;            // not the paper cell's (its bias is compiled in)
  int truth_points = SimulateOptions{}.points;  // the truths' DFN mesh and tolerance (the study's, beside the cell)
  double truth_rtol = SimulateOptions{}.rtol;
  bool default_truth_mesh() const {
    const SimulateOptions d;
    return truth_points == d.points && truth_points == d.radial && truth_rtol == d.rtol;
  }
  bool paper() const { return nominal.name == "paper"; }
};

struct Noise {
  const char* name;
  double v_mv, i_ma;
};
constexpr Noise kNoises[] = {{"v0.2mV", 0.2, 0.0}, {"i5mA", 0.0, 5.0}};
// Set 5's sensors have both noises at once: one case per truth.
constexpr Noise kSensorNoise[] = {{"v0.2mV+i5mA", 0.2, 5.0}};

std::vector<Noise> noises_of(int set) {
  if (set == 5) return {std::begin(kSensorNoise), std::end(kSensorNoise)};
  return {std::begin(kNoises), std::end(kNoises)};
}

// ---- the estimator arms ------------------------------------------------------------------

struct Arm {
  const char* name;
  const char* cli;  // what `bmssim estimate` takes for it
  fw::Profile profile;
  std::function<void(fw::Overrides&)> set;  // the arm's overrides (make_config refuses an unused one)
  bool other_cells_only = false;            // an ablation of what only another cell's calibration has
};

// Set 4's four tolerances as `bmssim estimate` takes them, and as the arms state them.
#define SET4_SPREAD_CLI "--spread-anode-i0 0.1732 --spread-cathode-i0 0.1732 --spread-transport 0.1155 --spread-area 0.01732"
void state_set4_spread(fw::Overrides& o) {
  o.spread_anode_i0_rel = 0.1732;
  o.spread_cathode_i0_rel = 0.1732;
  o.spread_transport_rel = 0.1155;
  o.spread_area_rel = 0.01732;
}

// Every tolerance of the blind sets stated as a datasheet's: set 4's spread, the inventory's
// +-1 % and the voltage sensor's +-0.5 mV, each a uniform bound's 1-sigma.
#define DATASHEET_CLI SET4_SPREAD_CLI " --inventory-sd 0.00577 --voltage-offset-sd-mv 0.2887"
void state_datasheet(fw::Overrides& o) {
  state_set4_spread(o);
  o.inventory_sd = 0.00577;
  o.voltage_offset_sd_mv = 0.2887;
}

// The datasheet and the initial film's tolerance: set 1's draw, +-20 % uniform, 1-sigma 0.1155.
#define DATASHEET_FILM_CLI DATASHEET_CLI " --film-initial-sd 0.1155"
void state_datasheet_film(fw::Overrides& o) {
  state_datasheet(o);
  o.film_initial_sd_rel = 0.1155;
}

const std::vector<Arm>& arms() {
  using P = fw::Profile;
  using O = fw::Overrides;
  static const std::vector<Arm> a = {
      {"best", "--settings best", P::best, [](O&) {}},
      {"best-no-learning", "--settings best --no-learning", P::best, [](O& o) { o.learning = false; }},
      {"best-no-inventory", "--settings best --no-inventory", P::best, [](O& o) { o.learn_inventory = false; }},
      {"best-no-bias", "--settings best --model-bias-ohm 0", P::best, [](O& o) { o.model_bias_ohm = 0.0; }},
      {"best-no-bias-levels", "--settings best --no-bias-levels", P::best,
       [](O& o) { o.model_bias_levels = false; }, true},
      {"best-bias-table-any-start", "--settings best --bias-table-any-start", P::best,
       [](O& o) { o.bias_table_any_start = true; }, true},
      {"best-no-charge-coverage", "--settings best --no-charge-coverage", P::best,
       [](O& o) { o.charge_coverage = false; }, true},
      {"best-misfit-stop", "--settings best --misfit-stop-s 120", P::best, [](O& o) { o.misfit_stop_s = 120.0; }},
      // The blind sets' inventory range (+-1 %) stated as a datasheet's tolerance: 1-sigma 0.01 / sqrt(3).
      {"best-inventory-sd", "--settings best --inventory-sd 0.00577", P::best, [](O& o) { o.inventory_sd = 0.00577; }},
      {"best-no-relinearise", "--settings best --relinearise 1", P::best, [](O& o) { o.relinearise_inventory = 1.0; }},
      {"best-no-warmup", "--settings best --warmup 0", P::best, [](O& o) { o.warmup_s = 0.0; }},
      {"best-no-offset", "--settings best --no-current-offset", P::best, [](O& o) { o.current_offset = false; }},
      {"best-voffset", "--settings best --voltage-offset", P::best, [](O& o) { o.voltage_offset = true; }},
      {"best-no-area", "--settings best --no-area-scale", P::best, [](O& o) { o.area_scale = false; }},
      {"best-area-in-model", "--settings best --area-scale-in-model", P::best,
       [](O& o) { o.area_scale_model_sees = true; }},
      {"best-no-hold", "--settings best --no-hold", P::best, [](O& o) { o.hold_until_settled = false; }},
      {"best-hold-restarted", "--settings best --hold-restarted-charge", P::best,
       [](O& o) { o.hold_restarted_charge = true; }},
      {"best-window1", "--settings best --resync-window 1", P::best, [](O& o) { o.resync_window_ticks = 1u; }},
      {"best-no-resync", "--settings best --no-resync", P::best, [](O& o) { o.resync = false; }},
      {"best-no-start-resync", "--settings best --no-start-resync", P::best, [](O& o) { o.resync_at_start = false; }},
      {"best-resync-at-once", "--settings best --resync-settle-s 0", P::best, [](O& o) { o.resync_settle_s = 0.0; }},
      // Set 4's spread stated as a datasheet would: a uniform +-a tolerance as its 1-sigma a / sqrt(3)
      // (kinetics +-30 %, transport +-20 %, area +-3 %); not tuned on any truth.
      {"best-stated-spread", "--settings best " SET4_SPREAD_CLI, P::best, state_set4_spread},
      // The same spread with the inventory's tolerance (best-inventory-sd): every tolerance of set 4 stated.
      {"best-stated-tolerances", "--settings best " SET4_SPREAD_CLI " --inventory-sd 0.00577", P::best,
       [](O& o) {
         state_set4_spread(o);
         o.inventory_sd = 0.00577;
       }},
      // Set 5's voltage offset U(-0.5, 0.5) mV stated as a front end's datasheet bound: 1-sigma
      // 0.5 / sqrt(3) mV; not tuned on any truth.
      {"best-stated-voltage", "--settings best --voltage-offset-sd-mv 0.2887", P::best,
       [](O& o) { o.voltage_offset_sd_mv = 0.2887; }},
      // Every tolerance a datasheet states at once (the cell's spread and inventory, the front end's
      // voltage accuracy, as the arms above): what a configured product would run.
      {"best-datasheet", "--settings best " DATASHEET_CLI, P::best, state_datasheet},
      // The same with the prior combined with the fitted level alone, the fit's growth on top.
      {"best-datasheet-level-only", "--settings best " DATASHEET_CLI " --fuse-level-only", P::best,
       [](O& o) {
         state_datasheet(o);
         o.fuse_level_only = true;
       }},
      // The datasheet's tolerances and the initial film's as the prior's sd wherever the prior is
      // reported, without and with the level alone.
      {"best-datasheet-film", "--settings best " DATASHEET_FILM_CLI, P::best, state_datasheet_film},
      {"best-datasheet-film-level-only", "--settings best " DATASHEET_FILM_CLI " --fuse-level-only", P::best,
       [](O& o) {
         state_datasheet_film(o);
         o.fuse_level_only = true;
       }},
      {"paper", "--settings paper", P::paper, [](O&) {}},
      {"paper-no-learning", "--settings paper --no-learning", P::paper, [](O& o) { o.learning = false; }},
      {"nominal-growth", "--settings nominal-growth", P::nominal_growth, [](O&) {}},
  };
  return a;
}

// What `bmssim estimate` reads from a truth.csv: the measured columns; the truth only to score.
EstimateData estimate_data_of(const SimulateRun& run) {
  EstimateData d;
  d.source = "study truth";
  const auto& s = run.result.samples;
  for (std::size_t i = 0; i < s.size(); ++i) {
    d.t_s.push_back(s[i].t_s);
    d.cycle.push_back(s[i].cycle);
    d.current_a.push_back(run.measured.current_a[i]);
    d.voltage_v.push_back(run.measured.voltage_v[i]);
    d.temperature_k.push_back(run.measured.temperature_k[i]);
    d.capacity_true_ah.push_back(s[i].capacity_ah);
    d.r_film_true_ohm_m2.push_back(s[i].r_film_ohm_m2);
    d.true_mode.push_back(s[i].mode);
    d.stoich_neg_true.push_back(s[i].stoich_neg);
    d.stoich_pos_true.push_back(s[i].stoich_pos);
  }
  return d;
}

json finite_or_null(double v) { return std::isfinite(v) ? json(v) : json(nullptr); }

// Over the CC-charge ticks of cycles 3.. (the truth's mode where the rows are the truth's): the
// share with the truth inside 2 sd, the median sd and the median |error| (% of the true film), the
// worst tick error once learning has opened in that charge; and the learning ticks per cycle.
void score_ticks(const EstimateResult& r, const std::vector<fw::Mode>& true_mode, json& j) {
  const bool use_true = true_mode.size() == r.rows.size();
  std::vector<double> sd, err;
  std::size_t inside = 0;
  double worst_tick = 0.0;
  bool learned_in_charge = false, scored_learning = false;
  std::size_t ref_end = 0, last_end = 0;  // the ends of the first and the last CC charge learned in
  std::map<int, std::size_t> learning;
  for (std::size_t i = 0; i < r.rows.size(); ++i) {
    const auto& row = r.rows[i];
    if (row.rcsi_active) ++learning[row.cycle];
    const bool cc = use_true ? true_mode[i] == fw::Mode::cc_charge : row.mode == fw::Mode::cc_charge;
    if (!cc) {
      if (learned_in_charge && i > 0) (ref_end == 0 ? ref_end : last_end) = i - 1;  // a learned charge ended
      learned_in_charge = false;
      continue;
    }
    learned_in_charge = learned_in_charge || row.rcsi_active;
    if (row.cycle < 3 || !std::isfinite(row.r_film_true_ohm_m2) || row.r_film_true_ohm_m2 == 0.0) continue;
    const double e = std::abs(row.r_film_est_ohm_m2 - row.r_film_true_ohm_m2);
    err.push_back(e / row.r_film_true_ohm_m2 * 100.0);
    if (learned_in_charge) {
      worst_tick = std::max(worst_tick, err.back());
      scored_learning = true;
    }
    if (std::isfinite(row.r_film_sd_ohm_m2)) {
      sd.push_back(row.r_film_sd_ohm_m2 / row.r_film_true_ohm_m2 * 100.0);
      if (e <= 2.0 * row.r_film_sd_ohm_m2) ++inside;
    }
  }
  j["within_2sd_pct_cycles_3_on"] = sd.empty() ? json(nullptr) : json(100.0 * static_cast<double>(inside) /
                                                                       static_cast<double>(sd.size()));
  j["sd_median_pct_cycles_3_on"] = finite_or_null(stats::median(sd));
  j["err_median_pct_cycles_3_on"] = finite_or_null(stats::median(err));
  j["worst_tick_err_pct_after_learning_cycles_3_on"] = scored_learning ? json(worst_tick) : json(nullptr);
  // The truth's own film growth between the two (growth_err_pct's denominator), % of the film.
  const auto true_at = [&r](std::size_t i) { return r.rows[i].r_film_true_ohm_m2; };
  j["true_growth_pct"] = last_end > ref_end ? json((true_at(last_end) - true_at(ref_end)) / true_at(ref_end) * 100.0)
                                            : json(nullptr);
  json by = json::array();
  for (const auto& c : r.cycles) by.push_back(learning.count(c.cycle) ? learning[c.cycle] : 0u);
  j["learning_ticks_by_cycle"] = by;
}

// Worst of the per-cycle medians over cycles 3.. (the measure), or of all when fewer.
json score(const EstimateResult& r, const std::vector<fw::Mode>& true_mode) {
  json j;
  double worst = 0.0, inv_worst = 0.0, cap_worst = 0.0;
  bool inv_any = false, cap_all = !r.cycles.empty();
  json medians = json::array(), inventory = json::array(), capacity = json::array(), within = json::array();
  for (const auto& c : r.cycles) {
    medians.push_back(c.r_film_err_median_pct);
    inventory.push_back(finite_or_null(c.inventory_err_end_pct));
    capacity.push_back(finite_or_null(c.capacity_err_pct));
    within.push_back(finite_or_null(c.film_within_2sd_pct));
    if (c.cycle >= 3 || r.cycles.size() < 3) {
      worst = std::max(worst, c.r_film_err_median_pct);
      if (std::isfinite(c.inventory_err_end_pct)) {
        inv_worst = std::max(inv_worst, std::abs(c.inventory_err_end_pct));
        inv_any = true;
      }
      // A cycle without a capacity (NaN: no equilibrium window) leaves the truth without one.
      if (std::isfinite(c.capacity_err_pct)) cap_worst = std::max(cap_worst, std::abs(c.capacity_err_pct));
      else cap_all = false;
    }
  }
  j["median_err_pct_by_cycle"] = medians;
  j["worst_err_pct_cycles_3_on"] = worst;
  j["inventory_err_end_pct_by_cycle"] = inventory;
  j["inventory_worst_abs_pct_cycles_3_on"] = inv_any ? json(inv_worst) : json(nullptr);
  j["capacity_err_pct_by_cycle"] = capacity;
  j["capacity_worst_abs_pct_cycles_3_on"] = cap_all ? json(cap_worst) : json(nullptr);
  j["film_within_2sd_pct_by_cycle"] = within;
  j["growth_err_pct"] = finite_or_null(r.growth_err_pct);
  score_ticks(r, true_mode, j);
  if (!r.rows.empty()) {
    const auto& last = r.rows.back();
    j["gain"] = last.growth_gain;
    j["film_initial_ohm_m2"] = last.film_initial_ohm_m2;
    j["inventory_deviation"] = last.inventory_deviation;
  }
  return j;
}

std::string case_name(const TruthDraw& t, const Noise& n) { return fmt::format("set{}-seed{:02d}-{}", t.set, t.seed, n.name); }

SimulateOptions simulate_options(const TruthDraw& t, const Noise& n, int cycles, const StudyCell& cell) {
  const CellParameters& nominal = cell.nominal;
  SimulateOptions so;
  so.cycles = cycles;
  if (!cell.paper()) {
    // Another cell cycles at its own 1C to its own limits, CV to C/20 (as scripts/any-cell-study.sh).
    so.cell = cell.arg;
    so.current_a = nominal.nominal_capacity_ah;
    so.cv_end_current_a = nominal.nominal_capacity_ah / 20.0;
  }
  so.points = so.radial = cell.truth_points;
  so.rtol = cell.truth_rtol;
  so.noise_v_mv = n.v_mv;
  so.noise_i_ma = n.i_ma;
  so.noise_t_k = t.noise_t_k;
  so.seed = static_cast<std::uint64_t>(t.seed);
  so.set = t.set_args(nominal);
  so.effects = t.effect_args();
  if (!t.protocol.empty()) so.protocol = t.protocol;
  so.quiet = true;
  return so;
}

// The `bmssim simulate` line that makes the case's truth (what --list-cases prints).
std::string simulate_command(const SimulateOptions& so) {
  std::string c = fmt::format("bmssim simulate --cell {} --protocol {} --cycles {} --noise-v-mv {} --noise-i-ma {}",
                              shell_word(so.cell), shell_word(so.protocol), so.cycles, so.noise_v_mv, so.noise_i_ma);
  if (so.cell != "paper") c += fmt::format(" --current-a {} --cv-end-current-a {}", so.current_a, so.cv_end_current_a);
  if (so.noise_t_k > 0.0) c += fmt::format(" --noise-t-k {}", so.noise_t_k);
  const SimulateOptions d;
  if (so.points != d.points || so.radial != d.radial || so.rtol != d.rtol)
    c += fmt::format(" --points {} --radial {} --rtol {}", so.points, so.radial, so.rtol);
  c += fmt::format(" --seed {}", so.seed);
  for (const auto& a : so.set) c += " --set " + a;
  for (const auto& e : so.effects) c += " --effect " + e;
  return c + " --out TRUTH";
}

bool wanted(const std::vector<std::string>& only, const std::string& arm) {
  return only.empty() || std::find(only.begin(), only.end(), arm) != only.end();
}

json truth_json(const TruthDraw& t) {
  return {{"r0_scale", t.r0_scale},
          {"growth_scale", t.growth_scale},
          {"side_i0_scale", t.i0_scale},
          {"inventory_scale", t.inventory_scale},
          {"conductivity_scale", t.conductivity_scale},
          {"diffusivity_scale_negative", t.diffusivity_neg},
          {"diffusivity_scale_positive", t.diffusivity_pos},
          {"electrolyte_diffusivity_scale", t.electrolyte_diffusivity},
          {"i0_scale_negative", t.i0_neg},
          {"i0_scale_positive", t.i0_pos},
          {"particle_size_sigma", t.particle_size_sigma},
          {"electrode_area_scale", t.area_scale},
          {"current_offset_a", t.current_offset_a},
          {"current_gain", t.current_gain},
          {"voltage_offset_v", t.voltage_offset_v},
          {"temperature_offset_k", t.temperature_offset_k},
          {"noise_t_k", t.noise_t_k},
          {"protocol", t.protocol.empty() ? std::string("cccv") : t.protocol},
          {"true_gain", t.true_gain()},
          {"temperature_k", t.temperature_k},
          {"self_heating", t.self_heating}};
}

// The reference estimators with the same information (nominal cell, measured columns, the
// sensor's noise from its data sheet).
void run_baselines(const EstimateData& data, const Noise& n, const CellParameters& nominal,
                   const std::vector<std::string>& only, json& j) {
  for (const char* method : {"ekf", "batch"}) {
    if (!wanted(only, method)) continue;
    baselines::BaselineOptions bo;
    bo.method = method;
    if (n.v_mv > 0.0) bo.sigma_v_v = n.v_mv * 1e-3;
    if (n.i_ma > 0.0) bo.sigma_i_a = n.i_ma * 1e-3;
    bo.ic = default_initial_conditions(nominal);
    try {
      const auto b = baselines::run_baseline(data, bo);
      EstimateResult r;
      r.rows = b.rows;
      r.cycles = b.scores;
      for (auto& c : r.cycles) c.inventory_err_end_pct = std::nan("");  // it estimates no inventory
      r.growth_err_pct = growth_error_pct(b.rows);
      json sj = score(r, data.true_mode);
      for (const char* k : {"gain", "film_initial_ohm_m2", "inventory_deviation"}) sj.erase(k);
      j["arms"][method] = sj;
    } catch (const std::exception& e) {
      j["baseline_failed"][method] = e.what();
    }
  }
}

// An arm's estimate options on the study's cell: on a cell other than the paper's, its nominal
// initial state, its design-time bias and the cell file's own effects, as `bmssim estimate --cell X
// --model reduced ARM_OPTIONS` sets them (one rule for both: use_design_bias, adopt_cell_effects).
EstimateOptions arm_options(const Arm& arm, const StudyCell& cell) {
  EstimateOptions o;
  o.profile = arm.profile;
  arm.set(o.overrides);
  if (cell.paper()) return o;
  o.ic = default_initial_conditions(cell.nominal);
  use_design_bias(o, cell.bias);
  adopt_cell_effects(o, cell.nominal);
  return o;
}

json run_case(const TruthDraw& t, const Noise& n, int cycles, const StudyCell& cell,
              const std::vector<std::string>& only) {
  const CellParameters& nominal = cell.nominal;
  const SimulateOptions so = simulate_options(t, n, cycles, cell);
  json j;
  j["case"] = case_name(t, n);
  j["cell"] = cell.arg;
  if (!cell.default_truth_mesh()) j["truth_mesh"] = {{"points", cell.truth_points}, {"rtol", cell.truth_rtol}};
  j["set"] = t.set;
  j["seed"] = t.seed;
  j["noise"] = {{"v_mv", n.v_mv}, {"i_ma", n.i_ma}};
  j["truth"] = truth_json(t);
  j["commands"] = {{"simulate", simulate_command(so)},
                   {"estimate", fmt::format("bmssim estimate --data TRUTH/truth.csv --cell {} --model reduced ARM_OPTIONS "
                                            "--out EST", shell_word(cell.arg))}};
  SimulateRun run;
  try {
    run = run_simulation(so, {});
  } catch (const std::exception& e) {
    j["truth_failed"] = e.what();
    return j;
  }
  const EstimateData data = estimate_data_of(run);
  // The current noise is folded in with the cell's own nominal reduced model.
  const double sigma_eff = effective_voltage_noise_v(n.v_mv * 1e-3, n.i_ma * 1e-3, so.current_a, nominal);
  for (const auto& arm : arms()) {
    if (!wanted(only, arm.name) || (only.empty() && arm.other_cells_only && cell.paper())) continue;
    const EstimateResult r = run_estimate(data, nominal, arm_options(arm, cell));
    j["arms"][arm.name] = score(r, data.true_mode);
    if (std::string(arm.name) == "best") j["crlb"] = film_bound_json(film_cramer_rao(r.rows, sigma_eff));
  }
  if (cell.paper()) run_baselines(data, n, nominal, only, j);
  if (j.contains("crlb")) j["crlb"]["sigma_v_effective_mv"] = sigma_eff * 1e3;
  return j;
}

// ---- aggregation -------------------------------------------------------------------------

// median / 90th percentile / worst; where higher is better (inside 2 sd), the 10th percentile and
// the lowest.
json distribution(std::vector<double> v, bool higher_is_better = false) {
  if (v.empty()) return json(nullptr);
  std::sort(v.begin(), v.end());
  if (higher_is_better) std::reverse(v.begin(), v.end());
  auto q = [&v](double p) {
    const double x = p * static_cast<double>(v.size() - 1);
    const auto i = static_cast<std::size_t>(x);
    return i + 1 < v.size() ? v[i] + (x - static_cast<double>(i)) * (v[i + 1] - v[i]) : v.back();
  };
  return {{"n", v.size()}, {"median", q(0.5)}, {"p90", q(0.9)}, {"worst", v.back()}};
}

json aggregate(const std::vector<json>& cases) {
  json agg;
  std::map<std::string, std::map<std::string, std::map<std::string, std::vector<double>>>> acc;
  // Per arm: the metric in the case's score -> its name in the aggregate (absent or null: skipped).
  const std::pair<const char*, const char*> metrics[] = {
      {"worst_err_pct_cycles_3_on", "film_worst_pct"},
      {"growth_err_pct", "growth_err_pct"},
      {"inventory_worst_abs_pct_cycles_3_on", "inventory_worst_pct"},
      {"capacity_worst_abs_pct_cycles_3_on", "capacity_worst_pct"},
      {"worst_tick_err_pct_after_learning_cycles_3_on", "film_worst_tick_pct"},
      {"within_2sd_pct_cycles_3_on", "within_2sd_pct"},
      {"sd_median_pct_cycles_3_on", "sd_median_pct"},
      {"err_median_pct_cycles_3_on", "err_median_pct"}};
  for (const auto& c : cases) {
    if (!c.contains("arms")) continue;
    const std::string name = c["case"].get<std::string>();
    const std::string group = fmt::format("set{}/{}", c["set"].get<int>(), name.substr(name.rfind('-') + 1));
    for (const auto& [arm, s] : c["arms"].items())
      for (const auto& [from, to] : metrics)
        if (s.contains(from) && s[from].is_number()) acc[group][arm][to].push_back(s[from].get<double>());
    if (!c.contains("crlb") || !c["crlb"].contains("film_sd_pct_worst_cycles_3_on")) continue;
    acc[group]["crlb"]["film_sd_pct"].push_back(c["crlb"]["film_sd_pct_worst_cycles_3_on"].get<double>());
    if (!c["crlb"]["inventory_sd_pct"].is_null())
      acc[group]["crlb"]["inventory_sd_pct"].push_back(c["crlb"]["inventory_sd_pct"].get<double>());
    if (!c["crlb"]["gain_sd"].is_null())
      acc[group]["crlb"]["gain_sd_pct_of_true"].push_back(c["crlb"]["gain_sd"].get<double>() /
                                                           c["truth"]["true_gain"].get<double>() * 100.0);
    if (c["crlb"].contains("growth_sd_pct") && c["crlb"]["growth_sd_pct"].is_number())
      acc[group]["crlb"]["growth_sd_pct"].push_back(c["crlb"]["growth_sd_pct"].get<double>());
  }
  for (auto& [group, by_arm] : acc)
    for (auto& [arm, metrics_of_arm] : by_arm)
      for (auto& [metric, values] : metrics_of_arm) agg[group][arm][metric] = distribution(values, metric == "within_2sd_pct");
  return agg;
}

// ---- report and figures ------------------------------------------------------------------

std::string fmt_dist(const json& d) {
  if (d.is_null()) return "-";
  return fmt::format("{:.2f} / {:.2f} / {:.2f}", d["median"].get<double>(), d["p90"].get<double>(),
                     d["worst"].get<double>());
}

int draw_figures(const fs::path& dir, const std::vector<json>& cases) {
  const fs::path fig = dir / "figures";
  fs::create_directories(fig);
  // gain: true vs learned; errors: best vs no-learning per case, by cycle.
  std::ofstream gain(fig / "gain.dat"), err(fig / "film_error.dat");
  for (int set : {1, 2}) {
    for (const auto& c : cases) {
      if (!c.contains("arms") || c["set"].get<int>() != set || !c["arms"].contains("best")) continue;
      gain << c["truth"]["true_gain"].get<double>() << ' ' << c["arms"]["best"].value("gain", 0.0) << '\n';
    }
    gain << "\n\n";
  }
  for (const char* arm : {"best", "best-no-learning", "paper"}) {
    for (const auto& c : cases) {
      if (!c.contains("arms") || c["set"].get<int>() != 1 || !c["arms"].contains(arm)) continue;
      const auto& m = c["arms"][arm]["median_err_pct_by_cycle"];
      for (std::size_t k = 0; k < m.size(); ++k) err << k + 1 << ' ' << m[k].get<double>() << '\n';
      err << '\n';
    }
    err << "\n";
  }
  gain.close();
  err.close();
  const std::string gp = fmt::format(
      "set terminal pngcairo size 1000,700 noenhanced\n"
      "set output '{0}/gain.png'\n"
      "set title 'Blind truths: learned growth gain g vs the truth (film_growth_scale x side_i0_scale)'\n"
      "set xlabel 'true gain (relative to the nominal law)'; set ylabel 'learned gain (best profile)'\n"
      "set grid; set key bottom right opaque box\n"
      "plot x title '1:1' lc rgb 'gray', '{0}/gain.dat' index 0 pt 7 title 'set 1', "
      "'{0}/gain.dat' index 1 pt 5 title 'set 2 (conductivity, diffusivities off too)'\n"
      "set output '{0}/film_error.png'\n"
      "set title 'Set 1: film error (median over each CC charge) per cycle, every truth and noise'\n"
      "set xlabel 'cycle'; set ylabel 'error [%]'; set logscale y; set xtics 1; set key outside below\n"
      "plot '{0}/film_error.dat' index 0 with linespoints lc rgb 'blue' title 'best', "
      "'{0}/film_error.dat' index 1 with linespoints lc rgb 'red' title 'best, learning off (control)', "
      "'{0}/film_error.dat' index 2 with linespoints lc rgb 'gray' title 'paper RCSI', "
      "2 with lines dt 2 lc rgb 'black' title '2 % target'\n",
      fig.string());
  write_file_atomically(fig / "figures.gp", gp);
  GnuplotOptions gnuplot;
  gnuplot.log = fig / "gnuplot.log";
  return run_gnuplot(fig / "figures.gp", gnuplot) == 0 ? 2 : 0;
}

void write_group_table(std::ostringstream& r, const std::string& group, const json& by_arm) {
  r << "## " << group << "\n\n| arm | film error % | growth_err_pct | inventory error % | capacity error % | "
       "worst tick after learning % | inside 2 sd % | median sd % | median error % |\n"
       "|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& [arm, m] : by_arm.items()) {
    if (arm == "crlb") continue;
    r << "| " << arm;
    // A metric some truths have no value of (e.g. a capacity the equilibrium cannot define): n shown.
    const std::size_t n = m.contains("film_worst_pct") ? m["film_worst_pct"].value("n", 0u) : 0u;
    for (const char* k : {"film_worst_pct", "growth_err_pct", "inventory_worst_pct", "capacity_worst_pct",
                          "film_worst_tick_pct", "within_2sd_pct", "sd_median_pct", "err_median_pct"}) {
      const json d = m.value(k, json());
      r << " | " << fmt_dist(d);
      if (!d.is_null() && d.value("n", 0u) != n) r << fmt::format(" (n = {} of {})", d.value("n", 0u), n);
    }
    r << " |\n";
  }
  if (by_arm.contains("crlb")) {
    const auto& b = by_arm["crlb"];
    r << "| CRLB (1 sd) | " << fmt_dist(b.value("film_sd_pct", json())) << " | gain sd % of true: "
      << fmt_dist(b.value("gain_sd_pct_of_true", json())) << "; growth (growth_err_pct's floor): "
      << fmt_dist(b.value("growth_sd_pct", json())) << " | " << fmt_dist(b.value("inventory_sd_pct", json()))
      << " | | | | | |\n";
  }
  r << "\n";
}

// Sets 4-6, one row per case: what was drawn beside set 1's unknowns and the best arm's numbers.
void write_case_table(std::ostringstream& r, const std::vector<json>& cases) {
  const bool any = std::any_of(cases.begin(), cases.end(), [](const json& c) { return c["set"].get<int>() >= 4; });
  if (!any) return;  // sets 1-3 have no per-case table
  r << "## Per case (sets 4-6, best arm)\n\n| case | drawn | film % | growth_err_pct (true growth %) | capacity % | inside 2 sd % | "
       "median sd % / median error % | learning ticks by cycle |\n|---|---|---|---|---|---|---|---|\n";
  auto num = [](const json& s, const char* k) {
    return s.contains(k) && s[k].is_number() ? fmt::format("{:.2f}", s[k].get<double>()) : std::string("-");
  };
  for (const auto& c : cases) {
    if (c["set"].get<int>() < 4) continue;
    const json& t = c["truth"];
    std::string drawn;
    if (c["set"] == 4)
      drawn = fmt::format("kappa {:.2f}, D_e {:.2f}, D_s -/+ {:.2f}/{:.2f}, i0 -/+ {:.2f}/{:.2f}, psd {:.2f}, area {:.3f}",
                          t["conductivity_scale"].get<double>(), t["electrolyte_diffusivity_scale"].get<double>(),
                          t["diffusivity_scale_negative"].get<double>(), t["diffusivity_scale_positive"].get<double>(),
                          t["i0_scale_negative"].get<double>(), t["i0_scale_positive"].get<double>(),
                          t["particle_size_sigma"].get<double>(), t["electrode_area_scale"].get<double>());
    if (c["set"] == 5)
      drawn = fmt::format("I offset {:+.1f} mA, gain {:+.2f} %, V offset {:+.3f} mV, T offset {:+.1f} K",
                          t["current_offset_a"].get<double>() * 1e3, t["current_gain"].get<double>() * 100.0,
                          t["voltage_offset_v"].get<double>() * 1e3, t["temperature_offset_k"].get<double>());
    if (c["set"] == 6) drawn = "`" + t["protocol"].get<std::string>() + "`";
    if (!c.contains("arms") || !c["arms"].contains("best")) {
      r << "| " << c["case"].get<std::string>() << " | " << drawn << " | "
        << (c.contains("truth_failed") ? "truth failed" : "best not run") << " | | | | | |\n";
      continue;
    }
    const json& s = c["arms"]["best"];
    r << "| " << c["case"].get<std::string>() << " | " << drawn << " | " << num(s, "worst_err_pct_cycles_3_on") << " | "
      << num(s, "growth_err_pct") << " (" << num(s, "true_growth_pct") << ") | "
      << num(s, "capacity_worst_abs_pct_cycles_3_on") << " | "
      << num(s, "within_2sd_pct_cycles_3_on") << " | " << num(s, "sd_median_pct_cycles_3_on") << " / "
      << num(s, "err_median_pct_cycles_3_on") << " | " << s.value("learning_ticks_by_cycle", json::array()).dump()
      << " |\n";
  }
  r << "\n";
}

void write_report(const fs::path& dir, const json& summary, int drawn) {
  std::ostringstream r;
  r << "# Blind identification study\n\n"
    << "Command: `" << summary["command"].get<std::string>() << "`\n\n"
    << "Cell: " << summary["options"].value("cell", std::string("paper"))
    << " (the truths' nominal cell and the firmware model's; another cell than the paper's cycles at its 1C to its "
       "voltage limits, CV to C/20, without the EKF and batch baselines, its bound for voltage noise alone). "
    << "Truth DFN: " << summary["options"].value("truth_mesh", json::object()).value("points", 20)
    << " volumes per region and per particle, rtol " << summary["options"].value("truth_mesh", json::object()).value("rtol", 1e-6)
    << ".\n\n"
    << "Truths drawn uniformly (seeded) from ranges the estimator never sees: set 1 initial film +-20 %, "
       "film-growth law x0.3..3, side-reaction i0 x0.5..2, lithium inventory +-1 %; set 2 adds electrolyte "
       "conductivity +-10 % and solid diffusivities +-20 %; set 3 is set 1 at a temperature drawn from 5-45 C, every "
       "third truth self-heating (lumped thermal model, 0.05 W/K), the estimator reading the measured temperature. "
       "Set 4 (spread) adds cell-to-cell spread to set 1: electrolyte conductivity and diffusivity and both solid "
       "diffusivities +-20 %, both electrodes' exchange currents +-30 %, a cathode particle-size spread (log-normal "
       "sigma 0.05-0.3) and the electrode area (capacity) +-3 %. Set 5 (sensors) is set 1 measured by a BMS front "
       "end: both noises at once (one case per truth), a current offset U(-10, 10) mA and gain U(-0.5, 0.5) %, a "
       "voltage offset U(-0.5, 0.5) mV, a temperature sensor 0.5 K off (sign drawn) with 0.2 K noise. Set 6 "
       "(protocols) is set 1 under a cycle drawn per truth: a partial discharge (0.5-1C, 20-90 % of the nominal "
       "capacity), a rest of 5 min-2 h, a CC charge at 0.3-1C from there, the CV hold, a rest of 2 min-1 h. "
       "No truth of sets 3-6 was used to choose anything: every seed of these sets is held out. Sets 1-4 and 6: "
       "each truth with sigma_v = 0.2 mV and with sigma_i = 5 mA. "
       "Film error = median over each CC charge; the tables show median / 90th percentile / worst over the truths "
       "of the worst such error in cycles 3 on; capacity error = the worst |capacity_err_pct| of cycles 3 on; "
       "worst tick = the largest CC-charge tick error in cycles 3 on once learning has opened in that charge; "
       "inside 2 sd, median sd and median error over the CC-charge ticks of cycles 3 on (% of the true film); for "
       "inside 2 sd the columns are median / 10th percentile / lowest. "
       "CRLB: the Cramer-Rao bound of the joint unknowns (initial film, growth gain, inventory) for the same data "
       "and noise.\n\n";
  for (const auto& [group, by_arm] : summary["aggregate"].items()) write_group_table(r, group, by_arm);
  write_case_table(r, summary["cases"].get<std::vector<json>>());
  r << "Arms: ";
  for (const auto& a : arms()) r << "`" << a.name << "` (" << a.cli << "); ";
  r << "`ekf`, `batch` (baselines)";
  r << "\n\nFailed truths: " << summary["truth_failures"].dump() << "\n\n";
  if (drawn > 0) r << "![gain](figures/gain.png)\n\n![film error](figures/film_error.png)\n";
  else r << "Figures not drawn (gnuplot missing): `gnuplot figures/figures.gp`.\n";
  write_file_atomically(dir / "report.md", r.str());
}

std::vector<int> parse_sets(const std::string& s) {
  std::vector<int> out;
  std::stringstream ss(s);
  std::string item;
  while (std::getline(ss, item, ',')) {
    if (item.size() != 1 || item[0] < '1' || item[0] > '6')
      throw InputError("--sets: '" + item + "' is not a set (1 to 6)");
    out.push_back(item[0] - '0');
  }
  if (out.empty()) throw InputError("--sets: give a set 1 to 6 or a list such as 1,2");
  return out;
}

std::vector<std::string> parse_arms(const std::vector<std::string>& only) {
  for (const auto& a : only) {
    const bool known = a == "ekf" || a == "batch" ||
                       std::any_of(arms().begin(), arms().end(), [&](const Arm& x) { return a == x.name; });
    if (known) continue;
    std::string names = "ekf, batch";
    for (const auto& x : arms()) names += std::string(", ") + x.name;
    throw InputError("--arms: unknown arm '" + a + "' for study blind (use " + names + ")");
  }
  return only;
}

// A stored case is reused when it is of this run's cell (a case of the paper cell stored before
// cells were recorded has none) and truth mesh (none recorded: the default) and has every arm
// this run asks for.
bool has_arms(const json& j, const std::vector<std::string>& only, const StudyCell& cell) {
  if (!j.is_object() || j.value("cell", std::string("paper")) != cell.arg) return false;
  const json mesh = cell.default_truth_mesh() ? json(nullptr)
                                              : json{{"points", cell.truth_points}, {"rtol", cell.truth_rtol}};
  if (j.value("truth_mesh", json(nullptr)) != mesh) return false;
  if (j.contains("truth_failed")) return true;
  if (!j.contains("arms")) return false;
  std::vector<std::string> need = only;
  if (need.empty()) {
    for (const auto& a : arms())
      if (!(a.other_cells_only && cell.paper())) need.push_back(a.name);
    if (cell.paper()) need.insert(need.end(), {"ekf", "batch"});
  }
  for (const auto& a : need)
    if (!j["arms"].contains(a) && !(j.contains("baseline_failed") && j["baseline_failed"].contains(a))) return false;
  return true;
}

// The study's cell; a file the firmware's model cannot use (naming the field), or a baseline
// asked for on a cell it does not model, is refused before any long work.
StudyCell study_cell(const std::string& arg, const std::vector<std::string>& only) {
  StudyCell cell;
  cell.arg = arg;
  cell.nominal = load_cell(arg);
  if (cell.paper()) return cell;
  (void)make_reduced_cell_record(cell.nominal);
  for (const char* b : {"ekf", "batch"})
    if (std::find(only.begin(), only.end(), b) != only.end())
      throw InputError(fmt::format("--arms {}: the baselines model the paper cell only; leave it out with --cell {}", b, arg));
  return cell;
}

}  // namespace

int run_blind_study(const BlindStudyOptions& o, const std::string& command) {
  const std::vector<int> sets = parse_sets(o.sets);
  const std::vector<std::string> only = parse_arms(o.arms);
  if (o.seeds < 1 || o.seeds > 1000) throw InputError("--seeds: must be 1..1000");
  if (o.cycles < 2 || o.cycles > 100) throw InputError("--cycles: must be 2..100");
  if (o.out.empty() && !o.list_cases) throw InputError("--out: required");
  StudyCell cell = study_cell(o.cell, only);
  cell.truth_points = o.truth_points;
  cell.truth_rtol = o.truth_rtol;
  const CellParameters& nominal = cell.nominal;
  struct Job {
    TruthDraw truth;
    Noise noise;
  };
  std::vector<Job> jobs;
  for (int set : sets)
    for (int seed = 1; seed <= o.seeds; ++seed)
      for (const auto& n : noises_of(set)) jobs.push_back({draw_truth(set, seed, nominal), n});
  if (o.list_cases) {
    for (const auto& job : jobs)
      std::printf("%s: %s\n", case_name(job.truth, job.noise).c_str(),
                  simulate_command(simulate_options(job.truth, job.noise, o.cycles, cell)).c_str());
    return 0;
  }
  if (!cell.paper()) {
    if (!o.quiet) std::fprintf(stderr, "study blind: the design-time bias of cell %s (its nominal DFN)\n", o.cell.c_str());
    cell.bias = design_time_bias(nominal);
  }
  const fs::path dir = fs::absolute(o.out);
  fs::create_directories(dir / "cases");
  std::vector<json> results(jobs.size());
  std::atomic<std::size_t> next{0}, done{0};
  std::mutex io;
  auto worker = [&]() {
    for (std::size_t k = next++; k < jobs.size(); k = next++) {
      const fs::path file = dir / "cases" / (case_name(jobs[k].truth, jobs[k].noise) + ".json");
      json j;
      if (fs::exists(file)) j = json::parse(read_text_file(file.string()));
      if (!has_arms(j, only, cell)) {
        j = run_case(jobs[k].truth, jobs[k].noise, o.cycles, cell, only);
        j["cycles"] = o.cycles;
        write_file_atomically(file, j.dump(2) + "\n");
      }
      results[k] = j;
      const std::size_t d = ++done;
      if (!o.quiet) {
        const std::lock_guard<std::mutex> lock(io);
        const bool best = j.contains("arms") && j["arms"].contains("best") &&
                          j["arms"]["best"].value("worst_err_pct_cycles_3_on", json()).is_number();
        const std::string line = best ? fmt::format("best {:.2f} %", j["arms"]["best"]["worst_err_pct_cycles_3_on"].get<double>())
                                      : (j.contains("truth_failed") ? "truth failed" : "done");
        std::fprintf(stderr, "study blind: %zu / %zu %s: %s\n", d, jobs.size(), j["case"].get<std::string>().c_str(),
                     line.c_str());
      }
    }
  };
  std::vector<std::thread> pool;
  for (int t = 0; t < std::max(1, o.jobs); ++t) pool.emplace_back(worker);
  for (auto& t : pool) t.join();
  json summary;
  summary["command"] = command;
  summary["options"] = {{"seeds", o.seeds}, {"cycles", o.cycles}, {"sets", sets}, {"arms", only}, {"cell", o.cell},
                         {"truth_mesh", {{"points", o.truth_points}, {"rtol", o.truth_rtol}}}};
  summary["cases"] = results;
  json failures = json::array();
  for (const auto& c : results)
    if (c.contains("truth_failed")) failures.push_back({{"case", c["case"]}, {"error", c["truth_failed"]}});
  summary["truth_failures"] = failures;
  summary["aggregate"] = aggregate(results);
  const int drawn = draw_figures(dir, results);
  write_report(dir, summary, drawn);
  write_file_atomically(dir / "summary.json", summary.dump(2) + "\n");
  if (!o.quiet) std::fprintf(stderr, "study blind: -> %s, %s\n", (dir / "summary.json").c_str(), (dir / "report.md").c_str());
  return static_cast<int>(failures.size());
}

}  // namespace bms::study
