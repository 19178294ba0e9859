#include "estimation/design_bias.hpp"

#include <algorithm>
#include <array>
#include <chrono>
#include <future>
#include <optional>
#include <string>
#include <tuple>
#include <cmath>
#include <limits>
#include <vector>

#include <fmt/format.h>

#include "estimation/estimate_run.hpp"
#include "io/input_error.hpp"
#include "sim/cycler.hpp"
#include "sim/truth_parameters.hpp"

namespace bms {
namespace {

constexpr int kCycles = 3;
constexpr int kMeshVolumes = 40;
constexpr double kRtol = 1e-9;
// The trusted span: a knot fits when the 90th percentile of |residual less the bias| over its
// ticks is within the innovation test's gate (5 x 0.3 mV, IdentifierFilmPath::Config): inside
// it the model's error is what the table removes; past it (a knee the table's median misses) the
// residual is the model's, not the film's.
constexpr double kTrustedQuantile = 0.9;
constexpr double kTrustedMisfitV = 1.5e-3;
constexpr double kCvEndCRate = 0.1;  // C/10: at C/20 the NMC template's anode fills at the separator (flat OCP above x = 0.9)
// The lean and rich levels' inventory deviation from nominal: the blind studies draw a cell's
// inventory within +-1 % of it (a cell's spread; FilmGrowthIdentifier identifies it).
constexpr double kInventoryLevelStep = 0.01;

// The coverage's charge currents below the calibration's 1C, highest first (DesignBias::coverage).
constexpr std::array<double, 3> kCoverageCRates = {0.7, 0.5, 0.3};

EstimateData nominal_run(const CellParameters& cell, double c_rate) {
  SimulationConfig cfg;
  cfg.cell = cell;
  cfg.mesh = {kMeshVolumes, kMeshVolumes, kMeshVolumes, kMeshVolumes};
  cfg.solver.rtol = kRtol;
  cfg.temperature_k = cell.thermal.ambient_temperature_k;
  cfg.ic = default_initial_conditions(cell);
  CccvProtocol p;
  p.cycles = kCycles;
  p.current_a = c_rate * cell.nominal_capacity_ah;
  p.cv_end_current_a = kCvEndCRate * cell.nominal_capacity_ah;
  p.v_min = cell.lower_voltage_v;
  p.v_max = cell.upper_voltage_v;
  const SimulationResult r = run_cccv(cfg, p);
  EstimateData d;
  d.source = "the nominal cell '" + cell.name + "' (design-time calibration)";
  for (const SampleRecord& s : r.samples) {
    d.t_s.push_back(s.t_s);
    d.current_a.push_back(s.current_a);
    d.voltage_v.push_back(s.voltage_v);
    d.cycle.push_back(s.cycle);
    d.r_film_true_ohm_m2.push_back(s.r_film_ohm_m2);
    d.true_mode.push_back(s.mode);
  }
  return d;
}

// The CC-charge ticks after the warm-up of the learning-off estimator on the nominal DFN, both at
// inventory deviation nu (the DFN's initial lithium scaled by 1 + nu, the estimator's nominal
// inventory and initial state with it): per tick the residual z, the charge current, the model's
// mean anode stoichiometry.
struct CalibrationTicks {
  std::vector<double> z_v, charge_a, stoich;
  std::vector<int> cycle;
};

CalibrationTicks calibration_ticks(const CellParameters& nominal, double nu, double c_rate = 1.0) {
  CellParameters cell = nominal;
  scale_initial_inventory(cell, 1.0 + nu);
  const EstimateData d = nominal_run(cell, c_rate);
  EstimateOptions o;
  o.model = "reduced";
  o.profile = fw::Profile::best;
  o.overrides.learning = false;
  o.overrides.model_bias_ohm = 0.0;  // the bias itself is what the run measures
  if (nu != 0.0) o.inventory_error_pct = 100.0 * nu;
  o.ic = default_initial_conditions(cell);
  const EstimateResult res = run_estimate(d, nominal, o);
  CalibrationTicks t;
  double start = std::nan("");
  for (const EstimateRow& row : res.rows) {
    if (row.mode != fw::Mode::cc_charge) {
      start = std::nan("");
      continue;
    }
    if (std::isnan(start)) start = row.t_s;
    if (row.t_s - start > res.config.warmup_s && row.model_current_a < 0.0) {
      t.z_v.push_back(row.z_v);
      t.charge_a.push_back(-row.model_current_a);
      t.stoich.push_back(row.model_stoich_neg);
      t.cycle.push_back(row.cycle);
    }
  }
  if (t.z_v.empty())
    throw RuntimeFailure(fmt::format("design-time bias of cell '{}': no CC-charge tick after the warm-up in the "
                                     "nominal run (inventory {:+.1f} %)",
                                     nominal.name, 100.0 * nu));
  return t;
}

double median_of(std::vector<double> v) {
  std::nth_element(v.begin(), v.begin() + static_cast<long>(v.size() / 2), v.end());
  return v[v.size() / 2];
}

// 10th / 50th / 90th percentile (nearest rank).
std::array<double, 3> percentiles(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  const auto at = [&](double q) { return v[static_cast<std::size_t>(q * static_cast<double>(v.size() - 1) + 0.5)]; };
  return {at(0.1), at(0.5), at(0.9)};
}

// The ticks' values grouped by the knot of t nearest each tick's stoichiometry (the end knots
// take the ticks beyond them).
std::array<std::vector<double>, fw::kModelBiasKnots> by_knot(const fw::ModelBiasTable<double>& t,
                                                             const std::vector<double>& stoich,
                                                             const std::vector<double>& values) {
  constexpr int kN = fw::kModelBiasKnots;
  const double step = (t.x_last - t.x_first) / (kN - 1);
  std::array<std::vector<double>, kN> bins;
  for (std::size_t i = 0; i < stoich.size(); ++i) {
    const long k = std::lround((stoich[i] - t.x_first) / step);
    bins[static_cast<std::size_t>(std::clamp<long>(k, 0, kN - 1))].push_back(values[i]);
  }
  return bins;
}

}  // namespace

fw::ModelBiasTable<double> bias_table_of(const std::vector<double>& stoich, const std::vector<double>& ratio_ohm) {
  constexpr int kN = fw::ModelBiasTable<double>::kKnots;
  if (stoich.empty() || stoich.size() != ratio_ohm.size())
    throw RuntimeFailure("design-time bias table: no CC-charge tick to build it from");
  const auto [lo, hi] = std::minmax_element(stoich.begin(), stoich.end());
  fw::ModelBiasTable<double> t;
  if (!(*hi > *lo)) return t;  // one state only: the constant says it all
  t.x_first = *lo;
  t.x_last = *hi;
  const auto bins = by_knot(t, stoich, ratio_ohm);
  std::array<bool, kN> have{};
  for (int k = 0; k < kN; ++k) {
    have[k] = !bins[k].empty();
    if (have[k]) t.ohm[k] = median_of(bins[k]);
  }
  for (int k = 0; k < kN; ++k) {  // a knot without ticks: linear between its nearest knots with ticks
    if (have[k]) continue;
    int a = k - 1, b = k + 1;
    while (a >= 0 && !have[a]) --a;
    while (b < kN && !have[b]) ++b;
    if (a < 0) t.ohm[k] = t.ohm[b];
    else if (b >= kN) t.ohm[k] = t.ohm[a];
    else t.ohm[k] = t.ohm[a] + (t.ohm[b] - t.ohm[a]) * (k - a) / double(b - a);
  }
  return t;
}

std::array<double, fw::kModelBiasKnots> knot_misfit_v(const fw::ModelBiasTable<double>& t,
                                                     const std::vector<double>& stoich,
                                                     const std::vector<double>& residual_v) {
  constexpr int kN = fw::kModelBiasKnots;
  std::array<double, kN> misfit{};
  if (!t.on()) return misfit;
  auto bins = by_knot(t, stoich, residual_v);
  for (int k = 0; k < kN; ++k) {
    auto& b = bins[static_cast<std::size_t>(k)];
    if (b.empty()) continue;
    for (double& v : b) v = std::fabs(v);
    std::sort(b.begin(), b.end());
    misfit[static_cast<std::size_t>(k)] = b[static_cast<std::size_t>(kTrustedQuantile * double(b.size() - 1) + 0.5)];
  }
  return misfit;
}

double trusted_span_end(const fw::ModelBiasTable<double>& t, const std::array<double, fw::kModelBiasKnots>& misfit_v,
                        double tolerance_v) {
  constexpr int kN = fw::kModelBiasKnots;
  int k = kN - 1;
  while (k >= 0 && misfit_v[static_cast<std::size_t>(k)] > tolerance_v) --k;
  if (k == kN - 1 || !t.on()) return std::numeric_limits<double>::infinity();
  const double step = (t.x_last - t.x_first) / (kN - 1);
  return t.x_first + (k + 0.5) * step;  // the upper edge of the highest knot that fits
}

namespace {

// One level's table over its ticks, less the nominal level's constant, with its trusted span, the
// per-knot misfit that set it and the ticks' residual less the constant and the table.
struct Level {
  fw::ModelBiasTable<double> table;
  std::array<double, fw::kModelBiasKnots> misfit_v{};
  std::vector<double> residual_v;
};

Level level_of(const CalibrationTicks& t, double bias_ohm) {
  std::vector<double> ratios(t.z_v.size());
  for (std::size_t i = 0; i < t.z_v.size(); ++i) ratios[i] = t.z_v[i] / t.charge_a[i] - bias_ohm;
  Level l{bias_table_of(t.stoich, ratios), {}, std::vector<double>(t.z_v.size())};
  for (std::size_t i = 0; i < t.z_v.size(); ++i)
    l.residual_v[i] = t.z_v[i] - (bias_ohm + l.table.at(t.stoich[i])) * t.charge_a[i];
  l.misfit_v = knot_misfit_v(l.table, t.stoich, l.residual_v);
  l.table.x_trusted_last = trusted_span_end(l.table, l.misfit_v, kTrustedMisfitV);
  return l;
}

// The 90th percentile of |z - (bias + table) I| over the ticks within the table's trusted span
// (the table off: the constant alone) from cycle first_cycle on.
double fit_p90_v(const CalibrationTicks& t, double bias_ohm, const fw::ModelBiasTable<double>& table, int first_cycle) {
  std::vector<double> e;
  for (std::size_t i = 0; i < t.z_v.size(); ++i)
    if (!(t.stoich[i] > table.x_trusted_last) && t.cycle[i] >= first_cycle)
      e.push_back(std::fabs(t.z_v[i] - (bias_ohm + table.at(t.stoich[i])) * t.charge_a[i]));
  return e.empty() ? std::numeric_limits<double>::infinity() : percentiles(e)[2];
}

// The coverage (ModelBiasTables::covered_charge_a_min, constant_alone_covered): the 1C
// calibration's bias against the nominal DFN's charges at the lower rates of kCoverageCRates,
// and the constant alone against the 1C charges. The rates' first cycle is left out: it holds the
// estimator's start (its initial state and power-up re-synchronisation), not the rate's bias. A
// rate fits when that percentile is within the trusted span's tolerance; the covered currents
// reach down from 1C over every rate that fits, to halfway to the first that does not (to 0.15C
// when all fit: halfway to none).
void set_coverage(DesignBias& b, const CellParameters& nominal, const CalibrationTicks& at_1c,
                  const std::vector<std::optional<CalibrationTicks>>& at_rates) {
  const fw::ModelBiasTable<double>& table = b.table.nominal();
  fw::ModelBiasTable<double> constant_only;
  constant_only.x_trusted_last = table.x_trusted_last;
  b.constant_alone_fit_p90_v = fit_p90_v(at_1c, b.bias_ohm, constant_only, 1);
  b.table.constant_alone_covered = !table.on() || b.constant_alone_fit_p90_v <= kTrustedMisfitV;
  double lowest = 1.0, below = 0.0;
  bool fits = true;
  for (std::size_t k = 0; k < kCoverageCRates.size(); ++k) {
    const double p90 =
        at_rates[k] ? fit_p90_v(*at_rates[k], b.bias_ohm, table, 2) : std::numeric_limits<double>::infinity();
    b.coverage.push_back({kCoverageCRates[k], p90});
    if (!fits) continue;
    fits = p90 <= kTrustedMisfitV;
    if (fits) lowest = kCoverageCRates[k];
    else below = kCoverageCRates[k];
  }
  b.table.covered_charge_a_min = 0.5 * (lowest + below) * nominal.nominal_capacity_ah;
}

}  // namespace

DesignBias design_time_bias(const CellParameters& nominal_in) {
  const auto wall0 = std::chrono::steady_clock::now();
  // The reduced model's own error against the plain DFN: the cell's effects (a contact
  // resistance, hysteresis, ...) are the model effects' to carry, not the bias's.
  CellParameters nominal = nominal_in;
  nominal.effects = CellEffectParameters{};
  // The lean and rich levels on other threads (independent DFN runs), the nominal one here.
  // A level whose DFN cannot run the protocol (an electrode full at the CV end: the cell's window
  // leaves no room for more lithium) stays the nominal level, said in DesignBias::level_notes.
  struct OffLevel {
    std::optional<CalibrationTicks> ticks;
    std::string failure;  // why the nominal DFN could not run there
  };
  const auto off_level = [&](double nu) {
    try {
      return OffLevel{calibration_ticks(nominal, nu), {}};
    } catch (const RuntimeFailure& e) {
      return OffLevel{std::nullopt, e.what()};
    }
  };
  auto lean = std::async(std::launch::async, off_level, -kInventoryLevelStep);
  auto rich = std::async(std::launch::async, off_level, kInventoryLevelStep);
  std::vector<std::future<std::optional<CalibrationTicks>>> rate_runs;
  for (double c_rate : kCoverageCRates)
    rate_runs.push_back(std::async(std::launch::async, [&nominal, c_rate]() -> std::optional<CalibrationTicks> {
      try {
        return calibration_ticks(nominal, 0.0, c_rate);
      } catch (const RuntimeFailure&) {
        return std::nullopt;  // a rate the nominal DFN cannot run: not covered
      }
    }));
  const CalibrationTicks t = calibration_ticks(nominal, 0.0);
  const OffLevel t_lean = lean.get(), t_rich = rich.get();
  std::vector<double> ratios(t.z_v.size()), with_constant(t.z_v.size());
  for (std::size_t i = 0; i < t.z_v.size(); ++i) ratios[i] = t.z_v[i] / t.charge_a[i];
  DesignBias b;
  b.bias_ohm = median_of(ratios);
  b.ticks = ratios.size();
  const Level nominal_level = level_of(t, b.bias_ohm);
  const fw::ModelBiasTable<double>& table = b.table.nominal() = nominal_level.table;
  b.knot_misfit_v = nominal_level.misfit_v;
  for (std::size_t i = 0; i < t.z_v.size(); ++i) with_constant[i] = t.z_v[i] - b.bias_ohm * t.charge_a[i];
  b.residual_constant_v = percentiles(with_constant);
  b.residual_table_v = percentiles(nominal_level.residual_v);
  if (table.on()) {  // a cell whose one state needs no table needs no levels either
    b.table.nu_step = kInventoryLevelStep;
    for (const auto& [k, off, name] : {std::tuple{0, &t_lean, "lean"}, std::tuple{2, &t_rich, "rich"}}) {
      b.table.level[k] = off->ticks ? level_of(*off->ticks, b.bias_ohm).table : table;
      if (!off->ticks)
        b.level_notes.push_back(fmt::format("the {} level ({:+.0f} % inventory) is the nominal one: the nominal DFN "
                                            "does not run the protocol there ({})",
                                            name, (k - 1) * 100.0 * kInventoryLevelStep, off->failure));
    }
  }
  std::vector<std::optional<CalibrationTicks>> at_rates;
  for (auto& f : rate_runs) at_rates.push_back(f.get());
  set_coverage(b, nominal, t, at_rates);
  b.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  return b;
}

void use_design_bias(EstimateOptions& o, const DesignBias& b) {
  if (o.profile != fw::Profile::best || o.overrides.model_bias_ohm.given) return;
  o.design_bias_ohm = b.bias_ohm;
  o.design_bias_table = b.table;
}

}  // namespace bms
