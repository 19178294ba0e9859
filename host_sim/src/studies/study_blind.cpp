#include "studies/study_blind.hpp"

#include <algorithm>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <map>
#include <mutex>
#include <random>
#include <sstream>
#include <thread>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "baselines/baseline_run.hpp"
#include "estimation/estimate_run.hpp"
#include "estimation/film_bound.hpp"
#include "io/gnuplot.hpp"
#include "io/input_error.hpp"
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

  // The film's growth rate relative to the nominal law: the law's factor times the side current's.
  double true_gain() const { return growth_scale * i0_scale; }

  std::vector<std::string> set_args(const CellParameters& nominal) const {
    std::vector<std::string> a = {
        fmt::format("r_film_initial_ohm_m2={}", r0_scale * nominal.side.initial_film_resistance_ohm_m2),
        fmt::format("film_growth_scale={}", growth_scale), fmt::format("side_i0_scale={}", i0_scale),
        fmt::format("inventory_scale={}", inventory_scale)};
    if (set == 3) a.push_back(fmt::format("temperature_k={}", temperature_k));
    if (set == 2) {
      a.push_back(fmt::format("conductivity_scale={}", conductivity_scale));
      a.push_back(fmt::format("diffusivity_scale_negative={}", diffusivity_neg));
      a.push_back(fmt::format("diffusivity_scale_positive={}", diffusivity_pos));
    }
    return a;
  }
};

// Uniform draws from the ranges; the estimator sees none of them.
TruthDraw draw_truth(int set, int seed) {
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
  return d;
}

// Set 3's self-heating truths: the lumped thermal model's heat-transfer coefficient (an 18650-size
// cell in still air; 298-302 K over a cycle at 25 C).
constexpr double kSelfHeatingWPerK = 0.05;

struct Noise {
  const char* name;
  double v_mv, i_ma;
};
constexpr Noise kNoises[] = {{"v0.2mV", 0.2, 0.0}, {"i5mA", 0.0, 5.0}};

// ---- the estimator arms ------------------------------------------------------------------

struct Arm {
  const char* name;
  const char* cli;  // what `bmssim estimate` takes for it
  fw::Profile profile;
  std::function<void(fw::Overrides&)> set;  // the arm's overrides (make_config refuses an unused one)
};

const std::vector<Arm>& arms() {
  using P = fw::Profile;
  using O = fw::Overrides;
  static const std::vector<Arm> a = {
      {"best", "--settings best", P::best, [](O&) {}},
      {"best-no-learning", "--settings best --no-learning", P::best, [](O& o) { o.learning = false; }},
      {"best-no-inventory", "--settings best --no-inventory", P::best, [](O& o) { o.learn_inventory = false; }},
      {"best-no-bias", "--settings best --model-bias-ohm 0", P::best, [](O& o) { o.model_bias_ohm = 0.0; }},
      {"best-no-relinearise", "--settings best --relinearise 1", P::best, [](O& o) { o.relinearise_inventory = 1.0; }},
      {"best-no-warmup", "--settings best --warmup 0", P::best, [](O& o) { o.warmup_s = 0.0; }},
      {"best-no-offset", "--settings best --no-current-offset", P::best, [](O& o) { o.current_offset = false; }},
      {"best-no-hold", "--settings best --no-hold", P::best, [](O& o) { o.hold_until_settled = false; }},
      {"best-window1", "--settings best --resync-window 1", P::best, [](O& o) { o.resync_window_ticks = 1u; }},
      {"best-no-resync", "--settings best --no-resync", P::best, [](O& o) { o.resync = false; }},
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

// Worst of the per-cycle medians over cycles 3.. (the measure), or of all when fewer.
json score(const EstimateResult& r) {
  json j;
  double worst = 0.0, inv_worst = 0.0;
  bool inv_any = false;
  json medians = json::array(), inventory = json::array();
  for (const auto& c : r.cycles) {
    medians.push_back(c.r_film_err_median_pct);
    inventory.push_back(finite_or_null(c.inventory_err_end_pct));
    if (c.cycle >= 3 || r.cycles.size() < 3) {
      worst = std::max(worst, c.r_film_err_median_pct);
      if (std::isfinite(c.inventory_err_end_pct)) {
        inv_worst = std::max(inv_worst, std::abs(c.inventory_err_end_pct));
        inv_any = true;
      }
    }
  }
  j["median_err_pct_by_cycle"] = medians;
  j["worst_err_pct_cycles_3_on"] = worst;
  j["inventory_err_end_pct_by_cycle"] = inventory;
  j["inventory_worst_abs_pct_cycles_3_on"] = inv_any ? json(inv_worst) : json(nullptr);
  j["growth_err_pct"] = finite_or_null(r.growth_err_pct);
  if (!r.rows.empty()) {
    const auto& last = r.rows.back();
    j["gain"] = last.growth_gain;
    j["film_initial_ohm_m2"] = last.film_initial_ohm_m2;
    j["inventory_deviation"] = last.inventory_deviation;
  }
  return j;
}

json bound_json(const FilmBound& b) {
  json j;
  j["valid"] = b.valid;
  j["gain_sd"] = finite_or_null(b.gain_sd);
  j["r0_sd_ohm_m2"] = finite_or_null(b.r0_sd_ohm_m2);
  j["inventory_sd_pct"] = finite_or_null(b.inventory_sd_pct);
  json by = json::array();
  double worst = 0.0;
  for (const auto& c : b.cycles) {
    by.push_back(finite_or_null(c.film_sd_pct));
    if (c.cycle >= 3 && std::isfinite(c.film_sd_pct)) worst = std::max(worst, c.film_sd_pct);
  }
  j["film_sd_pct_by_cycle"] = by;
  j["film_sd_pct_worst_cycles_3_on"] = worst;
  return j;
}

std::string case_name(const TruthDraw& t, const Noise& n) { return fmt::format("set{}-seed{:02d}-{}", t.set, t.seed, n.name); }

json run_case(const TruthDraw& t, const Noise& n, int cycles, const CellParameters& nominal) {
  SimulateOptions so;
  so.cycles = cycles;
  so.noise_v_mv = n.v_mv;
  so.noise_i_ma = n.i_ma;
  so.seed = static_cast<std::uint64_t>(t.seed);
  so.set = t.set_args(nominal);
  if (t.self_heating) so.effects.push_back(fmt::format("thermal={}", kSelfHeatingWPerK));
  so.quiet = true;
  json j;
  j["case"] = case_name(t, n);
  j["set"] = t.set;
  j["seed"] = t.seed;
  j["noise"] = {{"v_mv", n.v_mv}, {"i_ma", n.i_ma}};
  j["truth"] = {{"r0_scale", t.r0_scale},           {"growth_scale", t.growth_scale},
                {"side_i0_scale", t.i0_scale},      {"inventory_scale", t.inventory_scale},
                {"conductivity_scale", t.conductivity_scale}, {"diffusivity_scale_negative", t.diffusivity_neg},
                {"diffusivity_scale_positive", t.diffusivity_pos}, {"true_gain", t.true_gain()},
                {"temperature_k", t.temperature_k}, {"self_heating", t.self_heating}};
  std::string sim_cmd = fmt::format("bmssim simulate --cycles {} --noise-v-mv {} --noise-i-ma {} --seed {}", cycles,
                                    n.v_mv, n.i_ma, t.seed);
  for (const auto& a : so.set) sim_cmd += " --set " + a;
  for (const auto& e : so.effects) sim_cmd += " --effect " + e;
  j["commands"] = {{"simulate", sim_cmd + " --out TRUTH"},
                   {"estimate", "bmssim estimate --data TRUTH/truth.csv --model reduced ARM_OPTIONS --out EST"}};
  SimulateRun run;
  try {
    run = run_simulation(so, {});
  } catch (const std::exception& e) {
    j["truth_failed"] = e.what();
    return j;
  }
  const EstimateData data = estimate_data_of(run);
  const double sigma_eff = effective_voltage_noise_v(n.v_mv * 1e-3, n.i_ma * 1e-3, so.current_a);
  for (const auto& arm : arms()) {
    EstimateOptions o;
    o.profile = arm.profile;
    arm.set(o.overrides);
    const EstimateResult r = run_estimate(data, nominal, o);
    j["arms"][arm.name] = score(r);
    if (std::string(arm.name) == "best") j["crlb"] = bound_json(film_cramer_rao(r.rows, sigma_eff));
  }
  // The reference estimators with the same information (nominal cell, measured columns, the
  // sensor's noise from its data sheet).
  for (const char* method : {"ekf", "batch"}) {
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
      json sj = score(r);
      for (const char* k : {"gain", "film_initial_ohm_m2", "inventory_deviation"}) sj.erase(k);
      j["arms"][method] = sj;
    } catch (const std::exception& e) {
      j["baseline_failed"][method] = e.what();
    }
  }
  j["crlb"]["sigma_v_effective_mv"] = sigma_eff * 1e3;
  return j;
}

// ---- aggregation -------------------------------------------------------------------------

json distribution(std::vector<double> v) {
  if (v.empty()) return json(nullptr);
  std::sort(v.begin(), v.end());
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
  for (const auto& c : cases) {
    if (!c.contains("arms")) continue;
    const std::string group = fmt::format("set{}/{}", c["set"].get<int>(), c["case"].get<std::string>().substr(
                                                                               c["case"].get<std::string>().rfind('-') + 1));
    for (const auto& [arm, s] : c["arms"].items()) {
      acc[group][arm]["film_worst_pct"].push_back(s["worst_err_pct_cycles_3_on"].get<double>());
      if (!s["growth_err_pct"].is_null()) acc[group][arm]["growth_err_pct"].push_back(s["growth_err_pct"].get<double>());
      if (!s["inventory_worst_abs_pct_cycles_3_on"].is_null())
        acc[group][arm]["inventory_worst_pct"].push_back(s["inventory_worst_abs_pct_cycles_3_on"].get<double>());
    }
    acc[group]["crlb"]["film_sd_pct"].push_back(c["crlb"].value("film_sd_pct_worst_cycles_3_on", 0.0));
    if (!c["crlb"]["inventory_sd_pct"].is_null())
      acc[group]["crlb"]["inventory_sd_pct"].push_back(c["crlb"]["inventory_sd_pct"].get<double>());
    if (!c["crlb"]["gain_sd"].is_null())
      acc[group]["crlb"]["gain_sd_pct_of_true"].push_back(c["crlb"]["gain_sd"].get<double>() /
                                                           c["truth"]["true_gain"].get<double>() * 100.0);
  }
  for (auto& [group, by_arm] : acc)
    for (auto& [arm, metrics] : by_arm)
      for (auto& [metric, values] : metrics) agg[group][arm][metric] = distribution(values);
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
      if (!c.contains("arms") || c["set"].get<int>() != set) continue;
      gain << c["truth"]["true_gain"].get<double>() << ' ' << c["arms"]["best"].value("gain", 0.0) << '\n';
    }
    gain << "\n\n";
  }
  for (const char* arm : {"best", "best-no-learning", "paper"}) {
    for (const auto& c : cases) {
      if (!c.contains("arms") || c["set"].get<int>() != 1) continue;
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

void write_report(const fs::path& dir, const json& summary, int drawn) {
  std::ostringstream r;
  r << "# Blind identification study\n\n"
    << "Command: `" << summary["command"].get<std::string>() << "`\n\n"
    << "Truths drawn uniformly (seeded) from ranges the estimator never sees: set 1 initial film +-20 %, "
       "film-growth law x0.3..3, side-reaction i0 x0.5..2, lithium inventory +-1 %; set 2 adds electrolyte "
       "conductivity +-10 % and solid diffusivities +-20 %; set 3 is set 1 at a temperature drawn from 5-45 C, every "
       "third truth self-heating (lumped thermal model, 0.05 W/K), the estimator reading the measured temperature "
       "(no set-3 truth was used to choose anything: every set-3 seed is held out). Each truth with sigma_v = 0.2 mV and with sigma_i = 5 mA. "
       "Film error = median over each CC charge; the table shows median / 90th percentile / worst over the truths "
       "of the worst such error in cycles 3 on. CRLB: the Cramer-Rao bound of the joint unknowns (initial film, "
       "growth gain, inventory) for the same data and noise.\n\n";
  for (const auto& [group, by_arm] : summary["aggregate"].items()) {
    r << "## " << group << "\n\n| arm | film error % | growth_err_pct | inventory error % |\n|---|---|---|---|\n";
    for (const auto& [arm, m] : by_arm.items()) {
      if (arm == "crlb") continue;
      r << "| " << arm << " | " << fmt_dist(m.value("film_worst_pct", json())) << " | "
        << fmt_dist(m.value("growth_err_pct", json())) << " | " << fmt_dist(m.value("inventory_worst_pct", json()))
        << " |\n";
    }
    const auto& b = by_arm["crlb"];
    r << "| CRLB (1 sd) | " << fmt_dist(b.value("film_sd_pct", json())) << " | gain sd % of true: "
      << fmt_dist(b.value("gain_sd_pct_of_true", json())) << " | " << fmt_dist(b.value("inventory_sd_pct", json()))
      << " |\n\n";
  }
  r << "Arms: ";
  for (const auto& a : arms()) r << "`" << a.name << "` (" << a.cli << "); ";
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
    if (item != "1" && item != "2" && item != "3") throw InputError("--sets: '" + item + "' is not a set (1, 2 or 3)");
    out.push_back(std::stoi(item));
  }
  if (out.empty()) throw InputError("--sets: give 1, 2, 3 or a list such as 1,2");
  return out;
}

}  // namespace

int run_blind_study(const BlindStudyOptions& o, const std::string& command) {
  const std::vector<int> sets = parse_sets(o.sets);
  if (o.seeds < 1 || o.seeds > 1000) throw InputError("--seeds: must be 1..1000");
  if (o.cycles < 2 || o.cycles > 100) throw InputError("--cycles: must be 2..100");
  if (o.out.empty()) throw InputError("--out: required");
  const CellParameters nominal = load_cell("paper");
  struct Job {
    TruthDraw truth;
    Noise noise;
  };
  std::vector<Job> jobs;
  for (int set : sets)
    for (int seed = 1; seed <= o.seeds; ++seed)
      for (const auto& n : kNoises) jobs.push_back({draw_truth(set, seed), n});
  const fs::path dir = fs::absolute(o.out);
  fs::create_directories(dir / "cases");
  std::vector<json> results(jobs.size());
  std::atomic<std::size_t> next{0}, done{0};
  std::mutex io;
  auto worker = [&]() {
    for (std::size_t k = next++; k < jobs.size(); k = next++) {
      const fs::path file = dir / "cases" / (case_name(jobs[k].truth, jobs[k].noise) + ".json");
      json j;
      if (fs::exists(file)) {
        j = json::parse(read_text_file(file.string()));
      } else {
        j = run_case(jobs[k].truth, jobs[k].noise, o.cycles, nominal);
        j["cycles"] = o.cycles;
        write_file_atomically(file, j.dump(2) + "\n");
      }
      results[k] = j;
      const std::size_t d = ++done;
      if (!o.quiet) {
        const std::lock_guard<std::mutex> lock(io);
        const std::string best = j.contains("arms") ? fmt::format("{:.2f} %", j["arms"]["best"]["worst_err_pct_cycles_3_on"].get<double>())
                                                    : "truth failed";
        std::fprintf(stderr, "study blind: %zu / %zu %s: best %s\n", d, jobs.size(), j["case"].get<std::string>().c_str(),
                     best.c_str());
      }
    }
  };
  std::vector<std::thread> pool;
  for (int t = 0; t < std::max(1, o.jobs); ++t) pool.emplace_back(worker);
  for (auto& t : pool) t.join();
  json summary;
  summary["command"] = command;
  summary["options"] = {{"seeds", o.seeds}, {"cycles", o.cycles}, {"sets", sets}};
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
