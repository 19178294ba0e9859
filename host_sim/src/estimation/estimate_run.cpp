#include "estimation/estimate_run.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <map>
#include <memory>
#include <stdexcept>
#include <string>
#include <utility>

#include <fmt/format.h>

#include "bms/fw/estimation/bms_core.hpp"
#include "bms/fw/config/make_config.hpp"
#include "bms/fw/model/reduced_model_bias.hpp"
#include "cell/reduced_cell_record.hpp"
#include "dfn/dfn_model.hpp"
#include "estimation/full_dfn_main_model.hpp"
#include "io/child_process.hpp"
#include "io/csv_table.hpp"
#include "io/input_error.hpp"

namespace bms {

namespace {

EstimateData read_measured_file(const std::string& file, CurrentSign sign) {
  MeasuredProfile p = read_measured_profile(file, ProfileColumns::measured, sign);
  std::vector<double> dt(p.t_s.size() - 1);
  for (std::size_t i = 1; i < p.t_s.size(); ++i) dt[i - 1] = p.t_s[i] - p.t_s[i - 1];
  std::nth_element(dt.begin(), dt.begin() + static_cast<long>(dt.size() / 2), dt.end());
  const double step = dt[dt.size() / 2];
  if (step > kMaxControlSampleStepS)
    throw InputError(fmt::format("{}: sampled every {} s (the median step); the estimator needs a sample at least "
                                 "every {} s (coarser records leave the film's growth undetermined): log at {} s or "
                                 "finer",
                                 file, step, kMaxSampleStepS, kMaxSampleStepS));
  EstimateData d;
  d.source = file;
  d.median_step_s = step;
  // At most 1 s, and a whole fraction of the median step, so a record sampled every 30 s is
  // stepped at exactly 30 ticks per sample; rounded to 1 ns (times carry round-off).
  d.tick_s = std::round(step / std::ceil(step / kMaxModelTickS - 1e-9) * 1e9) / 1e9;
  d.t_s = std::move(p.t_s);
  d.current_a = std::move(p.current_a);
  d.voltage_v = std::move(p.voltage_v);
  d.temperature_k = std::move(p.temperature_k);
  d.cycle.assign(d.t_s.size(), 1);
  d.layout_note = fmt::format("{} layout, current read as {}; {} samples, median step {} s, model tick {} s "
                              "(the ticks between samples are caught up as the firmware catches up missed ticks)",
                              p.layout, p.current_negated ? "charge-positive" : "discharge-positive", d.t_s.size(),
                              step, d.tick_s);
  return d;
}

}  // namespace

EstimateData read_estimate_data(const std::string& file, CurrentSign sign) {
  const CsvTable t = read_csv(file, {"mode"});
  if (!t.has("t_s")) return read_measured_file(file, sign);
  for (const char* c : {"t_s", "current_meas_a", "voltage_meas_v"})
    if (!t.has(c))
      throw InputError(fmt::format("{}: needs a '{}' column (a truth.csv from 'bmssim simulate')", file, c));
  EstimateData d;
  d.source = file;
  d.t_s = t.numbers("t_s");
  d.current_a = t.numbers("current_meas_a");
  d.voltage_v = t.numbers("voltage_meas_v");
  // The sensor's temperature, never the truth's temperature_k (a truth.csv without the column:
  // none, the model stays at the cell's reference temperature).
  if (t.has("temperature_meas_k")) {
    d.temperature_k = t.numbers("temperature_meas_k");
    for (std::size_t i = 0; i < d.temperature_k.size(); ++i)
      if (!std::isfinite(d.temperature_k[i]) || d.temperature_k[i] <= 0.0)
        throw InputError(t.where(i, "temperature_meas_k") + ": must be a positive temperature in K");
  }
  if (d.t_s.size() < 2) throw InputError(file + ": needs at least 2 samples");
  d.cycle.assign(d.t_s.size(), 1);
  if (t.has("cycle")) {
    const auto& c = t.numbers("cycle");
    for (std::size_t i = 0; i < c.size(); ++i) d.cycle[i] = static_cast<int>(c[i]);
  }
  if (t.has("r_film_ohm_m2")) d.r_film_true_ohm_m2 = t.numbers("r_film_ohm_m2");
  if (t.has("stoich_neg") && t.has("stoich_pos")) {
    d.stoich_neg_true = t.numbers("stoich_neg");
    d.stoich_pos_true = t.numbers("stoich_pos");
  }
  // The truth's capacity is undefined where its inventory leaves the cell's equilibrium window
  // (simulate writes nan there): a scoring column, so such a row is not scored rather than refused.
  if (t.has("capacity_ah")) d.capacity_true_ah = t.numbers_or_nan("capacity_ah");
  if (t.has("mode")) {
    for (std::size_t i = 0; i < t.rows(); ++i) {
      Mode m{};
      if (!parse_mode(t.strings("mode")[i], m))
        throw InputError(t.where(i, "mode") + ": unknown mode '" + t.strings("mode")[i] + "'");
      d.true_mode.push_back(m);
    }
  }
  for (std::size_t i = 1; i < d.t_s.size(); ++i)
    if (!(d.t_s[i] > d.t_s[i - 1])) throw InputError(t.where(i, "t_s") + ": time must increase strictly");
  return d;
}

double fixed_tick_s(const EstimateData& d) {
  std::vector<double> dt(d.t_s.size() - 1);
  for (std::size_t i = 1; i < d.t_s.size(); ++i) dt[i - 1] = d.t_s[i] - d.t_s[i - 1];
  std::nth_element(dt.begin(), dt.begin() + static_cast<long>(dt.size() / 2), dt.end());
  const double med = dt[dt.size() / 2];
  for (std::size_t i = 1; i < d.t_s.size(); ++i) {
    const double s = d.t_s[i] - d.t_s[i - 1];
    if (std::abs(s - med) > 0.01 * med)
      throw InputError(fmt::format("{}: the firmware runs at a fixed tick; samples must be evenly spaced (median "
                                   "{} s) but t_s = {} s follows {} s after the previous sample",
                                   d.source, med, d.t_s[i], s));
  }
  // Times in a file carry round-off (t = k * 0.2 printed as 3276.6000000000004): the tick
  // is the median step rounded to 1 ns, so 0.2 s data runs with exactly the firmware's 0.2.
  return std::round(med * 1e9) / 1e9;
}

void require_sampling_for_learning(const EstimateData& d, bool learning) {
  if (!learning || !(d.median_step_s > kMaxSampleStepS)) return;
  throw InputError(fmt::format("{}: sampled every {} s (the median step); to learn, the estimator needs a sample at "
                               "least every {} s (coarser records leave the film's growth undetermined): log at {} s "
                               "or finer, or run the control run (--no-learning) for the nominal model and the "
                               "charges' counted capacity",
                               d.source, d.median_step_s, kMaxSampleStepS, kMaxSampleStepS));
}

double model_tick_s(const EstimateData& d) { return d.tick_s > 0.0 ? d.tick_s : fixed_tick_s(d); }

namespace {

double nominal_growth_ohm_m2_per_a_m3_s(const CellParameters& cell);

// What the firmware may see (the information rule): the measured columns and the sample
// clock. run_core gets only this; the truth is attached to its rows afterwards, for scoring.
struct MeasuredSeries {
  const std::vector<double>& t_s;
  const std::vector<double>& current_a;
  const std::vector<double>& voltage_v;
  const std::vector<double>& temperature_k;  // empty: no temperature measured
  const std::vector<int>& cycle;
  double sample_step_s;  // a measured file's median step when coarser than the tick, else 0
};

// One tick's output as a row of estimates.csv (the truth is attached afterwards, to score).
template <class Output>
EstimateRow row_of(const Output& out, double t_s, int cycle) {
  EstimateRow r{};
  r.t_s = t_s;
  r.cycle = cycle;
  r.mode = out.mode;
  r.rcsi_active = out.rcsi_active;
  r.r_film_est_ohm_m2 = out.r_film_est_ohm_m2;
  r.r_film_true_ohm_m2 = std::nan("");
  r.z_v = out.z_v;
  r.model_voltage_v = out.model_voltage_v;
  r.model_current_a = out.model_current_a;
  r.j_side_a_m3 = out.j_side_a_m3;
  r.li_loss_ah = out.li_loss_ah;
  r.film_initial_ohm_m2 = out.film_initial_ohm_m2;
  r.growth_gain = out.growth_gain;
  r.inventory_deviation = out.inventory_deviation;
  r.markov_v_per_ohm_m2 = out.markov_v_per_ohm_m2;
  r.inventory_sensitivity_v = out.inventory_sensitivity_v;
  r.growth_ohm_m2 = out.growth_ohm_m2;
  r.inventory_err_pct = std::nan("");
  r.r_film_sd_ohm_m2 = out.r_film_sd_ohm_m2;
  r.capacity_est_ah = out.capacity_ah;
  r.capacity_sd_ah = out.capacity_sd_ah;
  r.capacity_true_ah = std::nan("");
  r.innovation_test_ratio = out.innovation_test_ratio;
  r.current_offset_a = out.current_offset_a;
  r.voltage_offset_v = out.voltage_offset_v;
  r.area_scale = out.area_scale;
  r.status = out.status;
  r.model_stoich_neg = std::nan("");
  r.model_bias_v = std::nan("");
  return r;
}

// The model's mean anode stoichiometry and the identifier's design-time bias at it (volts, at the
// model's current: what the identifier subtracts from z), where the model and the path give them.
template <class Core, class Model>
void attach_model_bias(const Core& core, const Model& model, EstimateRow& r) {
  if constexpr (fw::kGivesStoichiometry<Model, double>) {
    r.model_stoich_neg = model.mean_stoich_neg();
    if constexpr (Core::FilmPath::kKind == fw::FilmPathKind::identifier)
      r.model_bias_v = -core.film_path().model_bias_ohm_of(model) * r.model_current_a;
  } else {
    (void)core;
    (void)model;
  }
}

// Ticks of dt_s from the record's start to each sample (the firmware's clock); a sample less
// than half a tick after the previous one shares its tick and is skipped (-1).
std::vector<long long> sample_ticks(const std::vector<double>& t_s, double dt_s) {
  std::vector<long long> k(t_s.size());
  long long last = -1;
  for (std::size_t i = 0; i < t_s.size(); ++i) {
    const long long ki = std::llround((t_s[i] - t_s.front()) / dt_s);
    k[i] = ki > last ? ki : -1;
    if (ki > last) last = ki;
  }
  return k;
}

// The core is told of the ticks that passed without a sample (in chunks: a counter of 32 bits).
template <class Core>
void tell_missed(Core& core, long long missed) {
  while (missed > 0) {
    const long long chunk = std::min<long long>(missed, 0x7FFFFFFFLL);
    core.ticks_missed(static_cast<std::uint32_t>(chunk));
    missed -= chunk;
  }
}

template <class Core, class Model>
void run_core_with(Model& model, const MeasuredSeries& d, const EstimateOptions& o, const CellParameters& cell,
                   double dt_s, EstimateResult& res, const EstimateProgress& progress) {
  constexpr int Nc = Core::kNc;
  typename Core::Config cfg{};
  const fw::Refusal refused = estimate_config<Core>(cell, o, dt_s, cfg);
  if (refused.option != nullptr) throw InputError(fmt::format("--{}: {}", refused.option, refused.reason));
  fw::adapt_to_sample_step(cfg, d.sample_step_s);
  res.config = summarise_config(cfg, Nc);
  Core core(cfg, model);
  const std::size_t n = d.t_s.size();
  const std::vector<long long> ticks = sample_ticks(d.t_s, dt_s);
  res.rows.reserve(n);
  res.theta_rows.reserve(n);
  long long last_tick = -1;
  for (std::size_t i = 0; i < n; ++i) {
    if (i % 256 == 0) throw_if_interrupted();  // SIGINT/SIGTERM: stop, nothing written
    if (ticks[i] < 0) {
      ++res.samples_skipped;
      continue;
    }
    if (last_tick >= 0) tell_missed(core, ticks[i] - last_tick - 1);
    last_tick = ticks[i];
    const double temperature_k = d.temperature_k.empty() ? 0.0 : d.temperature_k[i];
    const auto out = core.tick({d.voltage_v[i], d.current_a[i], true, temperature_k});
    EstimateRow r = row_of(out, d.t_s[i], d.cycle[i]);
    attach_model_bias(core, model, r);
    res.status |= out.status;
    if (fw::has_status(out.status, fw::FwStatus::kModelNotConverged)) ++res.newton_cap_hits;
    res.rows.push_back(r);
    res.theta_rows.emplace_back(out.theta, out.theta + 2 * Nc);
    if (progress && (i % 20000 == 0 || i + 1 == n)) progress(i + 1, n);
  }
  res.theta = res.theta_rows.back();
}

// The core with the film path the profile names (make_config.hpp's with_core_for).
template <int Nc, class Model>
void run_core(Model& model, const MeasuredSeries& d, const EstimateOptions& o, const CellParameters& cell,
              double dt_s, EstimateResult& res, const EstimateProgress& progress) {
  fw::with_core_for<double, Model, Nc, 0>(o.profile, [&](auto core) {
    run_core_with<typename decltype(core)::type>(model, d, o, cell, dt_s, res, progress);
  });
}

double nominal_growth_ohm_m2_per_a_m3_s(const CellParameters& cell) {
  return DfnModel::film_growth_factor(cell.side) / cell.negative.surface_area_per_volume_m();
}

fw::EffectParameters<double> effect_parameters(const EstimateOptions& o, const CellParameters& cell) {
  fw::EffectParameters<double> p = o.model_effects;
  p.nominal_capacity_ah = cell.nominal_capacity_ah;
  static const char* const kField[] = {"", "contact_resistance", "hysteresis", "hysteresis rate", "hysteresis branch",
                                       "nominal capacity (needed by hysteresis)", "current_offset", "current_gain"};
  if (const int bad = fw::invalid_effect_parameter(p); bad != 0)
    throw InputError(fmt::format("--model-effect {}: not usable with cell '{}'", kField[bad], cell.name));
  return p;
}

// Scoring only: the truth's film and, where the file has the stoichiometries, its solid lithium
// against the estimate (nominal x (1 + nu) less the model's own lithium loss).
// Solid lithium (mol) at mean stoichiometries: for the paper cell ReducedCell<double>'s own
// function (the same products, so the same numbers as before), else the cell's capacities.
double inventory_mol_of(const CellParameters& cell, double stoich_neg, double stoich_pos) {
  if (cell.name == "paper") return fw::ReducedCell<double>::inventory_of(stoich_neg, stoich_pos);
  const auto cap = [&](const ElectrodeParameters& e) {
    return e.max_concentration_mol_m3 * e.solid_fraction * e.thickness_m * cell.electrode_area_m2;
  };
  return stoich_neg * cap(cell.negative) + stoich_pos * cap(cell.positive);
}

void attach_truth(std::vector<EstimateRow>& rows, const EstimateData& d, const CellParameters& cell,
                  double nominal_inventory_mol) {
  for (std::size_t i = 0; i < rows.size(); ++i) {
    auto& r = rows[i];
    if (!d.r_film_true_ohm_m2.empty()) r.r_film_true_ohm_m2 = d.r_film_true_ohm_m2[i];
    if (!d.capacity_true_ah.empty()) r.capacity_true_ah = d.capacity_true_ah[i];
    if (d.stoich_neg_true.empty() || !(nominal_inventory_mol > 0.0)) continue;
    const double truth_mol = inventory_mol_of(cell, d.stoich_neg_true[i], d.stoich_pos_true[i]);
    const double est_mol = nominal_inventory_mol * (1.0 + r.inventory_deviation) - r.li_loss_ah * 3600.0 / fw::kFaradayC_mol;
    r.inventory_err_pct = (est_mol - truth_mol) / truth_mol * 100.0;
  }
}

template <class Model>
void dispatch_nc(Model& model, const MeasuredSeries& d, const EstimateOptions& o, const CellParameters& cell,
                 double dt_s, EstimateResult& res, const EstimateProgress& progress) {
  switch (o.overrides.nc.or_else(1)) {
    case 1: run_core<1>(model, d, o, cell, dt_s, res, progress); break;
    case 2: run_core<2>(model, d, o, cell, dt_s, res, progress); break;
    case 3: run_core<3>(model, d, o, cell, dt_s, res, progress); break;
    case 4: run_core<4>(model, d, o, cell, dt_s, res, progress); break;
    case 5: run_core<5>(model, d, o, cell, dt_s, res, progress); break;
    case 6: run_core<6>(model, d, o, cell, dt_s, res, progress); break;
    case 7: run_core<7>(model, d, o, cell, dt_s, res, progress); break;
    case 8: run_core<8>(model, d, o, cell, dt_s, res, progress); break;
    default: throw InputError(fmt::format("--nc must be 1..8 (got {})", o.overrides.nc.value));
  }
}

// A measured record gives no truth to check against: an estimate outside the physical range
// (a negative film) is a failure of the data's sampling, not a result.
void require_physical_film(const EstimateResult& res, const EstimateData& d) {
  if (!(d.tick_s > 0.0)) return;
  for (const EstimateRow& r : res.rows) {
    // The identifier's initial film is clipped into the film in use: negative there is the sign.
    const double film = std::min(r.r_film_est_ohm_m2, r.film_initial_ohm_m2);
    if (!(film >= 0.0) || !std::isfinite(r.r_film_est_ohm_m2))
      throw RuntimeFailure(fmt::format("{}: the film estimate left the physical range ({} ohm m2 at t = {} s) on a "
                                       "record sampled every {} s: log at 1 s (or finer) and run again",
                                       d.source, film, r.t_s, d.median_step_s));
  }
}

// The firmware's reduced model of cell traits Traits as the main model.
template <class Traits, class Mesh = fw::ReducedMesh<>>
void run_reduced(const MeasuredSeries& measured, const EstimateOptions& o, const CellParameters& cell, double dt_s,
                 EstimateResult& res, const EstimateProgress& progress) {
  using Model = fw::ReducedCell<double, Traits, Mesh>;
  Model model;
  model.init(o.ic.stoich_neg, o.ic.stoich_pos, o.ic.electrolyte_mol_m3);
  if (o.model_effects_on) {
    fw::EffectsModel<Model, fw::kAllCellEffects> augmented(model, effect_parameters(o, cell));
    dispatch_nc(augmented, measured, o, cell, dt_s, res, progress);
  } else {
    dispatch_nc(model, measured, o, cell, dt_s, res, progress);
  }
  res.model_bias_ohm = res.config.model_bias_ohm;
}

}  // namespace

void add_model_effect(EstimateOptions& o, const std::string& spec) {
  const auto eq = spec.find('=');
  if (eq == std::string::npos) throw InputError("--model-effect '" + spec + "': expected NAME=VALUE");
  const std::string name = spec.substr(0, eq), text = spec.substr(eq + 1);
  double value = 0.0;
  try {
    std::size_t used = 0;
    value = std::stod(text, &used);
    if (used != text.size()) throw std::invalid_argument(text);
  } catch (const std::exception&) {
    throw InputError("--model-effect '" + spec + "': VALUE must be a number");
  }
  if (!std::isfinite(value)) throw InputError("--model-effect '" + spec + "': VALUE must be a finite number");
  auto& p = o.model_effects;
  if (name == "contact_resistance") {
    if (value < 0.0) throw InputError("--model-effect contact_resistance: must be >= 0 ohm");
    p.contact_resistance_ohm = value;
  } else if (name == "hysteresis") {
    if (value < 0.0 || value > 0.5)
      throw InputError("--model-effect hysteresis: must be in [0, 0.5] V (half the gap between the branches)");
    p.hysteresis_v = value;
  } else if (name == "current_offset") {
    p.current_offset_a = value;
  } else if (name == "current_gain") {
    if (std::abs(value) >= 0.5) throw InputError("--model-effect current_gain: must be within +-0.5");
    p.current_gain = value;
  } else {
    throw InputError("--model-effect '" + name +
                     "': unknown effect (the firmware model has contact_resistance, hysteresis, current_offset, "
                     "current_gain)");
  }
  o.model_effects_on = true;
}

void adopt_cell_effects(EstimateOptions& o, const CellParameters& cell, const std::vector<std::string>& given) {
  if (o.model != "reduced") return;
  auto named = [&](const char* name) {
    for (const auto& e : given)
      if (e.rfind(std::string(name) + "=", 0) == 0) return true;
    return false;
  };
  const CellEffectParameters& fx = cell.effects;
  if (fx.contact_resistance_ohm > 0.0 && !named("contact_resistance"))
    add_model_effect(o, fmt::format("contact_resistance={:.17g}", fx.contact_resistance_ohm));
  if (fx.hysteresis_v > 0.0 && !named("hysteresis")) {
    add_model_effect(o, fmt::format("hysteresis={:.17g}", fx.hysteresis_v));
    if (fx.hysteresis_rate_per_soc > 0.0) o.model_effects.hysteresis_rate_per_soc = fx.hysteresis_rate_per_soc;
  }
}

fw::NominalCell estimate_nominal_cell(const CellParameters& cell, const EstimateOptions& o) {
  // The nominal inventory is the cell's design state, not the (possibly wrong) model start.
  const InitialConditions design = default_initial_conditions(cell);
  const double inventory_mol =
      inventory_mol_of(cell, design.stoich_neg, design.stoich_pos) * (1.0 + 0.01 * o.inventory_error_pct.or_else(0.0));
  // The full model is the DFN itself: no design-time bias to remove. The reduced model of a cell
  // other than the paper's: the bias its nominal DFN gives (estimation/design_bias.hpp).
  double bias_ohm = o.model == "full" ? 0.0 : fw::kPaperReducedModelBiasOhm;
  fw::ModelBiasTables<double> table{};
  if (o.model == "reduced" && cell.name != "paper") {
    table = o.design_bias_table;
    bias_ohm = o.design_bias_ohm;
    if (o.profile == fw::Profile::best && !o.overrides.model_bias_ohm.given && !std::isfinite(bias_ohm))
      throw InputError(fmt::format("--model reduced --cell {}: needs --model-bias-ohm (bmssim cell-config --cell {} "
                                   "computes it)",
                                   cell.name, cell.name));
    if (!std::isfinite(bias_ohm)) bias_ohm = 0.0;  // a profile that does not use the bias
  }
  return {inventory_mol,           cell.side.initial_film_resistance_ohm_m2,
          nominal_growth_ohm_m2_per_a_m3_s(cell), bias_ohm,
          cell.lower_voltage_v,    cell.upper_voltage_v,
          table,                   cell.nominal_capacity_ah};
}

fw::Overrides estimate_overrides(const EstimateOptions& o) {
  fw::Overrides v = o.overrides;
  if (o.model == "full") v.resync = false;  // the full DFN has no state observer
  return v;
}

void check_estimate_options(const EstimateOptions& o) {
  if (o.model != "reduced" && o.model != "full")
    throw InputError("--model must be 'reduced' or 'full' (got '" + o.model + "')");
  const fw::Overrides& v = o.overrides;
  if (o.model == "full" && v.resync.given && v.resync.value)
    throw InputError("--resync is a feature of the firmware model; use --model reduced");
  const fw::Refusal r = fw::unused_override(o.profile, estimate_overrides(o));
  if (r.option != nullptr)
    throw InputError(fmt::format("--{} is not used by --settings {}: {}", r.option, fw::profile_name(o.profile), r.reason));
  const bool inventory_used = o.model == "reduced" && (fw::observer_on(o.profile, v) || o.profile == fw::Profile::best);
  if (o.inventory_error_pct.given && !inventory_used)
    throw InputError(fmt::format("--inventory-error-pct is not used by --settings {} with --model {}: only the reduced "
                                 "model's state observer and --settings best read the nominal inventory",
                                 fw::profile_name(o.profile), o.model));
  if (o.points_given && o.model != "full") throw InputError("--points is not used by --model reduced (full model only)");
  auto bad = [](const auto& g, auto ok) { return g.given && !ok(g.value); };
  const auto finite = [](double x) { return std::isfinite(x); };
  if (bad(v.nc, [](int n) { return n >= 1 && n <= 8; })) throw InputError(fmt::format("--nc must be 1..8 (got {})", v.nc.value));
  if (bad(v.p0, [&](double x) { return finite(x) && x > 0.0; })) throw InputError("--p0 must be a positive number");
  if (bad(v.p0_y0, [&](double x) { return finite(x) && x > 0.0; })) throw InputError("--p0-y0 must be a positive number");
  if (bad(v.lambda, [](double x) { return x > 0.0 && x <= 1.0; })) throw InputError("--lambda must be in (0, 1]");
  if (bad(v.eta, [&](double x) { return finite(x) && x >= 0.0; })) throw InputError("--eta must be >= 0");
  if (bad(v.h_v_per_ohm_m2, [&](double x) { return finite(x) && x != 0.0; })) throw InputError("--h must be nonzero");
  if (bad(v.warmup_s, [&](double x) { return finite(x) && x >= 0.0; })) throw InputError("--warmup must be >= 0 s");
  if (bad(v.growth_scale, [&](double x) { return finite(x) && x >= 0.0; })) throw InputError("--growth-scale must be >= 0");
  if (bad(o.inventory_error_pct, [](double x) { return std::abs(x) < 50.0; }))
    throw InputError("--inventory-error-pct must be within +-50");
  if (bad(v.resync_current_a, [&](double x) { return finite(x) && x > 0.0; }))
    throw InputError("--resync-current must be a positive current in A");
  if (bad(v.r_film_init_ohm_m2, [&](double x) { return finite(x) && x >= 0.0 && x <= 1.0; }))
    throw InputError("--r-film-init: must be a finite film resistance in [0, 1] ohm m2");
  if (bad(v.theta0, [&](const fw::Theta0& t) { return t.count == 2 * v.nc.or_else(1); }))
    throw InputError(fmt::format("--theta0: needs 2 n_c = {} values (got {})", 2 * v.nc.or_else(1), v.theta0.value.count));
  const std::pair<const char*, const fw::Given<double>*> spreads[] = {{"spread-anode-i0", &v.spread_anode_i0_rel},
                                                                      {"spread-cathode-i0", &v.spread_cathode_i0_rel},
                                                                      {"spread-transport", &v.spread_transport_rel},
                                                                      {"spread-area", &v.spread_area_rel},
                                                                      {"film-initial-sd", &v.film_initial_sd_rel}};
  for (const auto& [name, g] : spreads)
    if (bad(*g, [](double x) { return x >= 0.0 && x <= 0.9; }))
      throw InputError(fmt::format("--{} must be a relative 1-sigma in [0, 0.9] (got {})", name, g->value));
  if (bad(v.voltage_offset_sd_mv, [](double x) { return x >= 0.0 && x <= 10.0; }))
    throw InputError(fmt::format("--voltage-offset-sd-mv must be a 1-sigma in [0, 10] mV (got {})", v.voltage_offset_sd_mv.value));
  if (bad(v.current_gain_sd_pct, [](double x) { return x >= 0.0 && x <= 5.0; }))
    throw InputError(fmt::format("--current-gain-sd-pct must be a 1-sigma in [0, 5] % (got {})", v.current_gain_sd_pct.value));
}

namespace {
void append_bytes(std::string& out, const void* p, std::size_t n) { out.append(static_cast<const char*>(p), n); }
void append_double(std::string& out, double v) { append_bytes(out, &v, sizeof v); }
}  // namespace

std::string firmware_stream(const EstimateData& d, bool learning) {
  const double dt_s = model_tick_s(d);
  const double sample_step_s = d.median_step_s > dt_s ? d.median_step_s : 0.0;
  const std::vector<long long> ticks = sample_ticks(d.t_s, dt_s);
  std::uint32_t count = 0;
  for (const long long k : ticks) count += k >= 0 ? 1u : 0u;
  std::string out;
  out.reserve(40 + static_cast<std::size_t>(count) * 4 * sizeof(double));
  out += "BMSMEAS3";
  const std::uint32_t words[2] = {count, 0u};
  append_bytes(out, words, sizeof words);
  append_double(out, dt_s);
  append_double(out, sample_step_s);
  append_double(out, learning ? 1.0 : 0.0);
  long long last_tick = -1;
  for (std::size_t i = 0; i < ticks.size(); ++i) {
    if (ticks[i] < 0) continue;  // shares the previous sample's tick: estimate skips it too
    const double missed = last_tick >= 0 ? static_cast<double>(ticks[i] - last_tick - 1) : 0.0;
    last_tick = ticks[i];
    append_double(out, d.voltage_v[i]);
    append_double(out, d.current_a[i]);
    append_double(out, d.temperature_k.empty() ? 0.0 : d.temperature_k[i]);
    append_double(out, missed);
  }
  return out;
}

EstimateResult run_estimate(const EstimateData& d, const CellParameters& cell, const EstimateOptions& options,
                            const EstimateProgress& progress) {
  const EstimateOptions& o = options;
  check_estimate_options(o);
  const double dt_s = model_tick_s(d);
  const auto wall0 = std::chrono::steady_clock::now();
  EstimateResult res;
  const MeasuredSeries measured{d.t_s, d.current_a, d.voltage_v, d.temperature_k, d.cycle,
                                d.median_step_s > dt_s ? d.median_step_s : 0.0};
  if (o.model == "reduced" && cell.name == "paper") {
    // The paper cell: the firmware's compiled-in configuration (PaperCellTraits).
    run_reduced<fw::PaperCellTraits>(measured, o, cell, dt_s, res, progress);
  } else if (o.model == "reduced") {
    // Any other cell: the firmware's model built from the cell's parameters, as the generated
    // configuration of a cross build holds them (cell/reduced_cell_record.hpp).
    const ReducedCellRecord record = make_reduced_cell_record(cell);
    const RuntimeCellScope scope(record);
    run_reduced<RuntimeCellTraits, AnyCellMesh>(measured, o, cell, dt_s, res, progress);
  } else if (o.model == "full") {
    SolverSettings s;
    s.rtol = o.rtol;
    InitialConditions ic = o.ic;
    ic.r_film_ohm_m2 = o.overrides.r_film_init_ohm_m2.or_else(cell.side.initial_film_resistance_ohm_m2);
    FullDfnMainModel model(cell, o.mesh, s, ic, cell.thermal.initial_temperature_k);
    if (o.model_effects_on) {
      fw::EffectsModel<FullDfnMainModel, fw::kAllCellEffects> augmented(model, effect_parameters(o, cell));
      dispatch_nc(augmented, measured, o, cell, dt_s, res, progress);
    } else {
      dispatch_nc(model, measured, o, cell, dt_s, res, progress);
    }
  }
  res.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  require_physical_film(res, d);
  attach_truth(res.rows, d, cell, res.config.nominal_inventory_mol);
  res.cycles = score_cycles(res.rows, !d.true_mode.empty(), d.true_mode);
  res.growth_err_pct = growth_error_pct(res.rows);
  return res;
}

std::vector<CycleScore> score_cycles(const std::vector<EstimateRow>& rows, bool use_true_mode,
                                     const std::vector<fw::Mode>& true_mode) {
  std::map<int, std::vector<double>> errs;
  std::map<int, std::size_t> last, within_2sd, with_sd, learning, misfit;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const auto& r = rows[i];
    if (r.rcsi_active) {
      ++learning[r.cycle];
      if (fw::has_status(r.status, fw::FwStatus::kModelMisfit)) ++misfit[r.cycle];
    }
    if (r.mode != fw::Mode::cc_charge) continue;
    if (use_true_mode && true_mode[i] != fw::Mode::cc_charge) continue;
    if (!std::isfinite(r.r_film_true_ohm_m2) || r.r_film_true_ohm_m2 == 0.0) continue;
    errs[r.cycle].push_back(std::abs(r.r_film_est_ohm_m2 - r.r_film_true_ohm_m2) / r.r_film_true_ohm_m2 * 100.0);
    last[r.cycle] = i;
    if (std::isfinite(r.r_film_sd_ohm_m2)) {
      ++with_sd[r.cycle];
      if (std::abs(r.r_film_est_ohm_m2 - r.r_film_true_ohm_m2) <= 2.0 * r.r_film_sd_ohm_m2) ++within_2sd[r.cycle];
    }
  }
  std::vector<CycleScore> out;
  for (auto& [cycle, e] : errs) {
    CycleScore s{};
    s.cycle = cycle;
    s.cc_charge_ticks = e.size();
    const std::size_t end_err_index = e.size() - 1;
    const double end_err = e[end_err_index];
    std::nth_element(e.begin(), e.begin() + static_cast<long>(e.size() / 2), e.end());
    s.r_film_err_median_pct = e[e.size() / 2];
    s.r_film_err_end_pct = end_err;
    s.r_film_true_end_ohm_m2 = rows[last[cycle]].r_film_true_ohm_m2;
    s.r_film_est_end_ohm_m2 = rows[last[cycle]].r_film_est_ohm_m2;
    s.inventory_err_end_pct = rows[last[cycle]].inventory_err_pct;
    const auto& end = rows[last[cycle]];
    s.capacity_err_pct = std::isfinite(end.capacity_true_ah) && std::isfinite(end.capacity_est_ah)
                             ? (end.capacity_est_ah - end.capacity_true_ah) / end.capacity_true_ah * 100.0
                             : std::nan("");
    s.film_within_2sd_pct = with_sd[cycle] > 0 ? 100.0 * static_cast<double>(within_2sd[cycle]) /
                                                     static_cast<double>(with_sd[cycle])
                                               : std::nan("");
    s.misfit_pct = learning[cycle] > 0
                       ? 100.0 * static_cast<double>(misfit[cycle]) / static_cast<double>(learning[cycle])
                       : 0.0;
    out.push_back(s);
  }
  return out;
}

GrowthSpan growth_span(const std::vector<EstimateRow>& rows) {
  // End of each CC charge: its last cc_charge row before another mode.
  std::vector<std::size_t> ends;
  std::size_t first_learning_end = rows.size();
  bool learned_in_phase = false;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (rows[i].mode != fw::Mode::cc_charge) continue;
    learned_in_phase = learned_in_phase || rows[i].rcsi_active;
    const bool end = i + 1 == rows.size() || rows[i + 1].mode != fw::Mode::cc_charge;
    if (!end) continue;
    if (std::isfinite(rows[i].r_film_true_ohm_m2)) ends.push_back(i);
    if (learned_in_phase && first_learning_end == rows.size() && std::isfinite(rows[i].r_film_true_ohm_m2))
      first_learning_end = i;
    learned_in_phase = false;
  }
  // The control run (no learning) is referenced to its first CC charge.
  if (first_learning_end == rows.size() && !ends.empty()) first_learning_end = ends.front();
  if (ends.empty() || ends.back() == first_learning_end) return {};
  return {first_learning_end, ends.back(), true};
}

double growth_error_pct(const std::vector<EstimateRow>& rows) {
  const GrowthSpan span = growth_span(rows);
  if (!span.valid) return std::nan("");
  const auto& ref = rows[span.ref];
  const auto& last = rows[span.last];
  const double true_growth = last.r_film_true_ohm_m2 - ref.r_film_true_ohm_m2;
  if (true_growth == 0.0) return std::nan("");
  const double est_growth = last.r_film_est_ohm_m2 - ref.r_film_est_ohm_m2;
  return std::abs(est_growth - true_growth) / std::abs(true_growth) * 100.0;
}

}  // namespace bms
