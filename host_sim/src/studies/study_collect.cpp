#include "studies/study_collect.hpp"

#include <algorithm>
#include <cmath>
#include <fmt/format.h>
#include <map>
#include <optional>
#include <set>
#include <utility>

#include "io/csv_table.hpp"
#include "io/input_error.hpp"
#include "io/text_file.hpp"
#include "sim/truth_output.hpp"
#include "studies/study_runner.hpp"
#include "io/statistics.hpp"

namespace bms::study {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// Only the truth columns the figures need; the table itself is dropped after loading.
struct Truth {
  std::vector<double> t_s, voltage_v, r_film;
  std::vector<int> cycle;
  std::vector<char> cc;  // true mode is constant-current charge
  json summary;
};

struct Estimates {
  std::vector<double> est, z;
};

json read_json(const fs::path& file) {
  try {
    return json::parse(read_text_file(file));
  } catch (const json::exception& e) {
    throw InputError(file.string() + ": not valid JSON: " + e.what());
  }
}

std::optional<Truth> load_truth(const fs::path& dir) {
  if (!fs::exists(dir / "summary.json")) return std::nullopt;
  const CsvTable t = read_csv(dir / "truth.csv", {"mode"});
  Truth out;
  out.t_s = t.numbers("t_s");
  out.voltage_v = t.numbers("voltage_v");
  out.r_film = t.numbers("r_film_ohm_m2");
  for (double c : t.numbers("cycle")) out.cycle.push_back(static_cast<int>(c));
  for (const auto& m : t.strings("mode")) out.cc.push_back(m == "cc_charge" ? 1 : 0);
  out.summary = read_json(dir / "summary.json");
  return out;
}

// The estimator writes one row per truth row; baselines without estimates.csv give nullopt.
std::optional<Estimates> load_estimates(const fs::path& dir, std::size_t rows) {
  if (!fs::exists(dir / "summary.json") || !fs::exists(dir / "estimates.csv")) return std::nullopt;
  const CsvTable t = read_csv(dir / "estimates.csv", {"mode", "status"});
  if (t.rows() != rows || !t.has("r_film_est_ohm_m2")) return std::nullopt;
  Estimates e;
  e.est = t.numbers("r_film_est_ohm_m2");
  if (t.has("z_v")) e.z = t.numbers("z_v");
  return e;
}

// [first, last] row of the constant-current charge of each cycle (one contiguous phase in CCCV).
std::map<int, std::pair<std::size_t, std::size_t>> cc_segments(const Truth& t) {
  std::map<int, std::pair<std::size_t, std::size_t>> seg;
  for (std::size_t i = 0; i < t.cc.size(); ++i) {
    if (!t.cc[i]) continue;
    auto [it, inserted] = seg.try_emplace(t.cycle[i], i, i);
    if (!inserted) it->second.second = i;
  }
  return seg;
}

using stats::median;

json stats(const std::vector<double>& v) {
  std::vector<double> x;
  for (double a : v)
    if (std::isfinite(a)) x.push_back(a);
  if (x.empty()) return {{"n", 0}};
  double mean = 0.0;
  for (double a : x) mean += a;
  mean /= static_cast<double>(x.size());
  double var = 0.0;
  for (double a : x) var += (a - mean) * (a - mean);
  const double sd = x.size() > 1 ? std::sqrt(var / static_cast<double>(x.size() - 1)) : 0.0;
  return {{"n", x.size()},
          {"mean", mean},
          {"std", sd},
          {"min", *std::min_element(x.begin(), x.end())},
          {"max", *std::max_element(x.begin(), x.end())}};
}

// Writes gnuplot data blocks (separated by two blank lines, selected with `index`).
class DatFile {
 public:
  void comment(const std::string& c) { text_ += "# " + c + "\n"; }
  void row(std::initializer_list<double> cols) {
    std::string line;
    for (double c : cols) line += (line.empty() ? "" : " ") + (std::isfinite(c) ? fmt::format("{:.9g}", c) : "nan");
    text_ += line + "\n";
  }
  void gap() { text_ += "\n"; }  // breaks the line inside a block
  void end_block() {
    text_ += "\n\n";
    ++blocks_;
  }
  int blocks() const { return blocks_; }
  void write(const fs::path& file) const { write_file_atomically(file, text_); }

 private:
  std::string text_;
  int blocks_ = 0;
};

struct CaseOut {
  CaseSpec spec;
  fs::path dir;
};

// The arm's per-cycle values of its metric (summary.json "cycles"[].METRIC).
std::vector<double> per_cycle(const json& summary, const std::string& metric) {
  std::vector<double> v;
  if (!summary.contains("cycles")) return v;
  for (const auto& c : summary["cycles"])
    v.push_back(c.contains(metric) && c[metric].is_number() ? c[metric].get<double>() : std::nan(""));
  return v;
}

double mean_of(const std::vector<double>& v) {
  double s = 0.0;
  std::size_t n = 0;
  for (double a : v)
    if (std::isfinite(a)) s += a, ++n;
  return n ? s / static_cast<double>(n) : std::nan("");
}

double max_of(const std::vector<double>& v) {
  double m = std::nan("");
  for (double a : v)
    if (std::isfinite(a) && !(a <= m)) m = a;
  return m;
}

// The q-quantile of |v|.
double quantile_abs(const std::vector<double>& v, double q) {
  std::vector<double> a;
  for (double x : v)
    if (std::isfinite(x)) a.push_back(std::abs(x));
  return stats::quantile(a, q);
}

// A y range that shows the body of the curves: the last seconds of a CC phase, where the
// compared runs reach the voltage limit at slightly different times, jump by many mV.
void clip_y(FigureData& f, double bound) {
  if (std::isfinite(bound) && bound > 0.0) {
    f.y_min = -bound;
    f.y_max = bound;
  }
}

constexpr int kEvery = 5;  // figure data: every 5th 0.2 s sample (1 s) is plenty for a PNG
// Arms reporting this per-cycle field estimate R_film (estimates.csv); the bound does not.
constexpr const char* kErrorMetric = "r_film_err_median_pct";

using Segments = std::map<int, std::pair<std::size_t, std::size_t>>;

std::vector<CaseOut> find_cases(const fs::path& out_dir) {
  std::vector<CaseOut> cases;
  if (fs::is_directory(out_dir / "cases")) {
    for (const auto& e : fs::directory_iterator(out_dir / "cases")) {
      const fs::path cj = e.path() / "case.json";
      if (!fs::exists(cj)) continue;
      cases.push_back({case_from_json(read_json(cj), cj.string()), e.path()});
    }
  }
  if (cases.empty() && !fs::exists(out_dir / "plan.json"))
    throw InputError(out_dir.string() + "/cases: no case outputs (case.json) to collect");
  std::sort(cases.begin(), cases.end(), [](const CaseOut& a, const CaseOut& b) { return a.spec.name < b.spec.name; });
  return cases;
}

// The arm's per-cycle errors from its summary.json, or nullopt when the step has no output.
std::optional<json> arm_errors(const CaseOut& c, const Step& s) {
  const fs::path sj = c.dir / s.name / "summary.json";
  if (!fs::exists(sj)) return std::nullopt;
  const auto v = per_cycle(read_json(sj), s.metric);
  return json{{"metric", s.metric}, {"by_cycle", v}, {"mean_pct", mean_of(v)}, {"worst_cycle_pct", max_of(v)}};
}

// Last row of cycle k (x.cycle.size() when the cycle is absent).
std::size_t last_row(const Truth& x, int k) {
  std::size_t last = x.cycle.size();
  for (std::size_t i = 0; i < x.cycle.size(); ++i)
    if (x.cycle[i] == k) last = i;
  return last;
}

// One collection: the cases, the reference case's truth and its CC-charge segments, and the
// figures gathered so far. Each study part is one member.
class Collector {
 public:
  Collector(const fs::path& out_dir, Collected& col, std::vector<CaseOut> cases, const CaseOut& ref_case, Truth ref)
      : fig_dir_(out_dir / "figures"), col_(col), cases_(std::move(cases)), ref_case_(ref_case),
        ref_(std::move(ref)), ref_seg_(cc_segments(ref_)) {}

  void figure08();
  void figure11();
  void noise_study();
  void ic_study();

 private:
  const CaseOut* find_case(const std::string& name) const {
    for (const auto& c : cases_)
      if (c.spec.name == name) return &c;
    return nullptr;
  }
  const std::optional<Estimates>& ref_estimates(const std::string& arm);
  std::vector<double> cc1_voltage_diff(const Truth& other, DatFile& d) const;
  double noise_deviation_pct(const CaseOut& c, const Step& s);
  std::optional<json> noise_level(const NoiseLevel& level);
  void noise_figure(const NoiseLevel& level, const CaseOut& c);
  json ic_model(const Step& s, DatFile& d14, DatFile& d15, FigureData& f14, FigureData& f15, json& output_error);
  void ic_model_figures(json& ic);
  json ic_truth_case(const Truth& t, DatFile& d16, DatFile& d17, double& worst_end, double& worst_cc1,
                     std::vector<double>& all_dv);
  void ic_truth_figures(json& ic);

  fs::path fig_dir_;
  Collected& col_;
  std::vector<CaseOut> cases_;
  const CaseOut& ref_case_;
  Truth ref_;
  Segments ref_seg_;
  std::map<std::string, std::optional<Estimates>> ref_est_;  // arm -> the clean case's estimates
};

const std::optional<Estimates>& Collector::ref_estimates(const std::string& arm) {
  auto it = ref_est_.find(arm);
  if (it == ref_est_.end()) it = ref_est_.emplace(arm, load_estimates(ref_case_.dir / arm, ref_.t_s.size())).first;
  return it->second;
}

// Figure 8: truth voltage change between successive cycles vs relative film growth.
void Collector::figure08() {
  DatFile d;
  d.comment("relative film growth since the previous cycle (%), voltage change (mV); CC charge, same time since its start");
  FigureData f{"fig08", "Truth: voltage change vs relative film growth between successive cycles (CC charge)",
               "film resistance growth since the previous cycle (%)", "voltage change (mV)", {}, "lines"};
  json pairs = json::array();
  std::vector<double> all_dv;
  for (const auto& [k, seg] : ref_seg_) {
    const auto next = ref_seg_.find(k + 1);
    if (next == ref_seg_.end()) continue;
    const std::size_t n = std::min(seg.second - seg.first, next->second.second - next->second.first) + 1;
    std::vector<double> dv, dr;
    for (std::size_t j = 0; j < n; ++j) {
      const std::size_t a = seg.first + j, b = next->second.first + j;
      dv.push_back((ref_.voltage_v[b] - ref_.voltage_v[a]) * 1e3);
      dr.push_back((ref_.r_film[b] - ref_.r_film[a]) / ref_.r_film[a] * 100.0);
      if (j % kEvery == 0) d.row({dr.back(), dv.back()});
    }
    d.end_block();
    f.curves.push_back({d.blocks() - 1, 1, 2, fmt::format("cycle {} vs {}", k + 1, k)});
    std::vector<double> adv;
    for (double v : dv) adv.push_back(std::abs(v));
    all_dv.insert(all_dv.end(), dv.begin(), dv.end());
    pairs.push_back({{"cycles", {k, k + 1}},
                     {"dv_median_abs_mv", median(adv)},
                     {"dv_max_abs_mv", max_of(adv)},
                     {"film_growth_median_pct", median(dr)}});
  }
  json growth = json::array();
  for (const auto& c : ref_.summary.value("cycles", json::array())) growth.push_back(c.value("growth_pct", 0.0));
  col_.summary["fig08"] = {{"pairs", pairs}, {"film_growth_per_cycle_pct", growth}};
  clip_y(f, 2.0 * quantile_abs(all_dv, 0.95));
  d.write(fig_dir_ / "fig08.dat");
  col_.figures.push_back(f);
}

// Voltage (mV) of `other` minus the reference in cycle 1 CC charge, same time since its start.
std::vector<double> Collector::cc1_voltage_diff(const Truth& other, DatFile& d) const {
  std::vector<double> adv;
  const auto seg_o = cc_segments(other);
  if (!seg_o.count(1) || !ref_seg_.count(1)) return adv;
  const auto [a0, a1] = ref_seg_.at(1);
  const auto [b0, b1] = seg_o.at(1);
  const std::size_t n = std::min(a1 - a0, b1 - b0) + 1;
  for (std::size_t j = 0; j < n; ++j) {
    const double dv = (other.voltage_v[b0 + j] - ref_.voltage_v[a0 + j]) * 1e3;
    adv.push_back(std::abs(dv));
    if (j % kEvery == 0) d.row({static_cast<double>(j) * (ref_.t_s[1] - ref_.t_s[0]), dv});
  }
  d.end_block();
  return adv;
}

// Figure 11: truth voltage at lower currents against 2.50 A.
void Collector::figure11() {
  DatFile d;
  d.comment("time since the start of cycle 1 CC charge (s), V(I) - V(2.50 A) (mV)");
  FigureData f{"fig11", "Truth: voltage difference to 2.50 A (cycle 1, CC charge)", "time since CC charge start (s)",
               "V(I) - V(2.50 A) (mV)", {}, "lines"};
  json currents = json::array();
  std::vector<double> all_dv;
  for (const auto& c : cases_) {
    if (c.spec.kind != "current") continue;
    const auto t = load_truth(c.dir / "truth");
    if (!t) continue;
    const auto adv = cc1_voltage_diff(*t, d);
    all_dv.insert(all_dv.end(), adv.begin(), adv.end());
    f.curves.push_back({d.blocks() - 1, 1, 2, fmt::format("{} A", c.spec.current_a)});
    currents.push_back({{"current_a", c.spec.current_a},
                        {"delta_current_ma", (2.5 - c.spec.current_a) * 1e3},
                        {"dv_median_abs_mv", median(adv)},
                        {"dv_max_abs_mv", max_of(adv)}});
  }
  if (currents.empty()) return;
  col_.summary["fig11"] = {{"currents", currents}};
  clip_y(f, 1.5 * quantile_abs(all_dv, 0.95));
  d.write(fig_dir_ / "fig11.dat");
  col_.figures.push_back(f);
}

// The noise's own share: RMS deviation (%) from the same arm on the noise-free data; NaN when
// either has no estimates.
double Collector::noise_deviation_pct(const CaseOut& c, const Step& s) {
  const auto& r = ref_estimates(s.name);
  const auto est = r ? load_estimates(c.dir / s.name, ref_.t_s.size()) : std::nullopt;
  if (!est) return std::nan("");
  double ss = 0.0;
  std::size_t n = 0;
  for (const auto& [k, seg] : ref_seg_)
    for (std::size_t i = seg.first; i <= seg.second; ++i) {
      const double d = (est->est[i] - r->est[i]) / ref_.r_film[i];
      if (std::isfinite(d)) ss += d * d, ++n;
    }
  return n ? std::sqrt(ss / static_cast<double>(n)) * 100.0 : std::nan("");
}

// Per-case errors of one noise level, then mean and spread over its seeds per arm; nullopt
// when no case has this level.
std::optional<json> Collector::noise_level(const NoiseLevel& level) {
  struct Acc {
    std::string metric;
    std::vector<double> mean, worst, dev;
  };
  std::map<std::string, Acc> acc;
  std::vector<const CaseOut*> seed_cases;
  for (const auto& c : cases_) {
    if (c.spec.kind != "noise" || c.spec.noise_v_mv != level.noise_v_mv || c.spec.noise_i_ma != level.noise_i_ma)
      continue;
    seed_cases.push_back(&c);
    for (const auto& s : c.spec.steps) {
      if (s.name == "truth") continue;
      const auto e = arm_errors(c, s);
      if (!e) continue;
      auto& a = acc[s.name];
      a.metric = s.metric;
      a.mean.push_back((*e)["mean_pct"].get<double>());
      a.worst.push_back((*e)["worst_cycle_pct"].get<double>());
      if (s.metric != kErrorMetric) continue;  // the bound estimates nothing
      const double dev = noise_deviation_pct(c, s);
      if (!std::isnan(dev)) a.dev.push_back(dev);
    }
  }
  if (seed_cases.empty()) return std::nullopt;
  json arms = json::object();
  for (const auto& [name, a] : acc)
    arms[name] = {{"metric", a.metric},
                  {"err_mean_over_cycles_pct", stats(a.mean)},
                  {"err_worst_cycle_pct", stats(a.worst)},
                  {"dev_from_noise_free_rms_pct", stats(a.dev)}};
  noise_figure(level, *seed_cases.front());
  return json{{"level", level.name},
              {"noise_v_mv", level.noise_v_mv},
              {"noise_i_ma", level.noise_i_ma},
              {"seeds", seed_cases.size()},
              {"arms", arms}};
}

// Figures 9, 10, 12, 13: the first seed's estimates beside the truth in CC charge.
void Collector::noise_figure(const NoiseLevel& level, const CaseOut& c) {
  const std::map<std::string, std::string> fig_of = {
      {"v0.02mV", "fig09"}, {"v0.2mV", "fig10"}, {"i0.5mA", "fig12"}, {"i5mA", "fig13"}};
  DatFile d;
  d.comment("time (h), film resistance (1e-3 ohm m2) in CC charge; block 0 truth, then one block per arm");
  FigureData f{fig_of.at(level.name),
               fmt::format("Film resistance with {} noise, sigma = {} (case {})",
                           level.noise_v_mv > 0 ? "output" : "input",
                           level.noise_v_mv > 0 ? fmt::format("{} mV", level.noise_v_mv)
                                                : fmt::format("{} mA", level.noise_i_ma),
                           c.spec.name),
               "time (h)", "film resistance (1e-3 ohm m^2)", {}, "lines"};
  for (const auto& [k, seg] : ref_seg_) {
    for (std::size_t i = seg.first; i <= seg.second; i += kEvery) d.row({ref_.t_s[i] / 3600.0, ref_.r_film[i] * 1e3});
    d.gap();
  }
  d.end_block();
  // Magnified like the paper's figures: the truth's range +-15 %.
  double r_lo = 1e300, r_hi = 0.0;
  for (const auto& [k, seg] : ref_seg_)
    for (std::size_t i = seg.first; i <= seg.second; ++i) r_lo = std::min(r_lo, ref_.r_film[i]), r_hi = std::max(r_hi, ref_.r_film[i]);
  f.y_min = r_lo * 0.85e3;
  f.y_max = r_hi * 1.15e3;
  for (const auto& s : c.spec.steps) {
    if (s.name == "truth" || s.metric != kErrorMetric) continue;
    const auto est = load_estimates(c.dir / s.name, ref_.t_s.size());
    if (!est) continue;
    for (const auto& [k, seg] : ref_seg_) {
      for (std::size_t i = seg.first; i <= seg.second; i += kEvery) d.row({ref_.t_s[i] / 3600.0, est->est[i] * 1e3});
      d.gap();
    }
    d.end_block();
    f.curves.push_back({d.blocks() - 1, 1, 2, s.name});
  }
  f.curves.push_back({0, 1, 2, "truth"});  // drawn last, on top
  d.write(fig_dir_ / (f.id + ".dat"));
  col_.figures.push_back(f);
}

void Collector::noise_study() {
  json ref_arms = json::object();
  for (const auto& s : ref_case_.spec.steps) {
    if (s.name == "truth") continue;
    if (auto e = arm_errors(ref_case_, s)) ref_arms[s.name] = *e;
  }
  col_.summary["noise_free"] = ref_arms;
  json levels = json::array();
  for (const auto& level : noise_levels())
    if (auto l = noise_level(level)) levels.push_back(*l);
  col_.summary["noise"] = levels;
}

// One arm with model IC error -1 / 0 / +1 %: its curves in figures 14-15 and the change of its
// identified film resistance against the same arm without IC error (empty: no estimates).
json Collector::ic_model(const Step& s, DatFile& d14, DatFile& d15, FigureData& f14, FigureData& f15,
                         json& output_error) {
  json per_ic = json::object();
  const auto& r0 = ref_estimates(s.name);
  if (!r0) return per_ic;
  const bool has_cc1 = ref_seg_.count(1) != 0;
  const auto [c0, c1] = has_cc1 ? ref_seg_.at(1) : std::pair<std::size_t, std::size_t>{0, 0};
  const double dt = ref_.t_s.size() > 1 ? ref_.t_s[1] - ref_.t_s[0] : 0.2;
  double worst_c1 = std::nan(""), worst_any = std::nan("");
  for (double p : {-1.0, 0.0, 1.0}) {
    std::optional<Estimates> e;
    const CaseOut* mc = nullptr;
    if (p == 0.0) {
      e = r0;
    } else {
      mc = find_case(fmt::format("model-ic{:+}", p));
      if (mc) e = load_estimates(mc->dir / s.name, ref_.t_s.size());
    }
    if (!e) continue;
    const std::string key = fmt::format("{:+}", p);
    if (has_cc1) {
      std::vector<double> z;
      for (std::size_t i = c0; i <= c1; ++i) {
        if (!e->z.empty()) z.push_back(e->z[i] * 1e3);
        if ((i - c0) % kEvery == 0) {
          if (!e->z.empty()) d14.row({static_cast<double>(i - c0) * dt, e->z[i] * 1e3});
          d15.row({static_cast<double>(i - c0) * dt, e->est[i] * 1e3});
        }
      }
      if (!e->z.empty()) {
        d14.end_block();
        f14.curves.push_back({d14.blocks() - 1, 1, 2, fmt::format("{} IC {} %", s.name, key)});
        output_error[s.name][key] = {{"z_median_mv", median(z)}};
      }
      d15.end_block();
      f15.curves.push_back({d15.blocks() - 1, 1, 2, fmt::format("{} IC {} %", s.name, key)});
    }
    if (p == 0.0) continue;
    std::vector<double> by_cycle;
    for (const auto& [k, seg] : ref_seg_) {
      std::vector<double> ch;
      for (std::size_t i = seg.first; i <= seg.second; ++i) ch.push_back(std::abs(e->est[i] - r0->est[i]) / r0->est[i] * 100.0);
      by_cycle.push_back(median(ch));
    }
    const auto err = mc ? arm_errors(*mc, s) : std::nullopt;
    per_ic[key] = {{"change_median_by_cycle_pct", by_cycle}, {"error_vs_truth", err ? *err : json()}};
    if (!by_cycle.empty() && !(by_cycle.front() <= worst_c1)) worst_c1 = by_cycle.front();
    const double w = max_of(by_cycle);
    if (!(w <= worst_any)) worst_any = w;
  }
  if (!per_ic.empty()) {
    per_ic["cycle1_change_max_pct"] = worst_c1;
    per_ic["worst_cycle_change_max_pct"] = worst_any;
  }
  return per_ic;
}

// Figures 14-15: output error and identified film resistance, model IC error -1 / 0 / +1 %.
void Collector::ic_model_figures(json& ic) {
  DatFile d14, d15;
  d14.comment("time since cycle 1 CC charge start (s), z = model - measured voltage (mV)");
  d15.comment("time since cycle 1 CC charge start (s), identified film resistance (1e-3 ohm m2)");
  FigureData f14{"fig14", "Output error in cycle 1 CC charge, model initial-condition error", "time since CC charge start (s)",
                 "z = y_model - y (mV)", {}, "lines"};
  FigureData f15{"fig15", "Identified film resistance in cycle 1 CC charge, model initial-condition error",
                 "time since CC charge start (s)", "film resistance (1e-3 ohm m^2)", {}, "lines"};
  const auto [c0, c1] = ref_seg_.count(1) ? ref_seg_.at(1) : std::pair<std::size_t, std::size_t>{0, 0};
  const double dt = ref_.t_s.size() > 1 ? ref_.t_s[1] - ref_.t_s[0] : 0.2;
  for (std::size_t i = c0; i <= c1 && ref_seg_.count(1); i += kEvery) d15.row({static_cast<double>(i - c0) * dt, ref_.r_film[i] * 1e3});
  d15.end_block();
  json identified = json::object(), output_error = json::object();
  for (const auto& s : ref_case_.spec.steps) {
    if (s.name == "truth" || s.metric != kErrorMetric) continue;
    json per_ic = ic_model(s, d14, d15, f14, f15, output_error);
    if (!per_ic.empty()) identified[s.name] = per_ic;
  }
  ic["identified_r_film_change"] = identified;
  ic["output_error"] = output_error;
  f15.curves.push_back({0, 1, 2, "truth"});  // drawn last, on top
  // The paper's RCSI may swing to many times the truth; show 0 .. twice the true value.
  if (ref_seg_.count(1)) f15.y_max = 2e3 * ref_.r_film[c0];
  if (identified.empty()) return;
  d14.write(fig_dir_ / "fig14.dat");
  d15.write(fig_dir_ / "fig15.dat");
  col_.figures.push_back(f14);
  col_.figures.push_back(f15);
}

// One truth run started with an initial-condition error: its curves in figures 16-17 and its changes.
json Collector::ic_truth_case(const Truth& t, DatFile& d16, DatFile& d17, double& worst_end,
                              double& worst_cc1, std::vector<double>& all_dv) {
  const std::size_t n = std::min(t.t_s.size(), ref_.t_s.size());
  for (std::size_t i = 0; i < n; i += kEvery)
    d16.row({ref_.t_s[i] / 3600.0, (t.r_film[i] - ref_.r_film[i]) / ref_.r_film[i] * 100.0});
  d16.end_block();
  // At the end of each cycle (cycle-aligned, so a shifted switching time does not count).
  std::vector<double> end_change;
  for (int k = 1; k <= ref_case_.spec.cycles; ++k) {
    const std::size_t a = last_row(ref_, k), b = last_row(t, k);
    if (a >= ref_.cycle.size() || b >= t.cycle.size()) continue;
    end_change.push_back((t.r_film[b] - ref_.r_film[a]) / ref_.r_film[a] * 100.0);
    const double ac = std::abs(end_change.back());
    if (!(ac <= worst_end)) worst_end = ac;
  }
  // In cycle 1's CC charge, same time since its start: where the paper compares (figures 14-16).
  double cc1 = std::nan("");
  const auto seg_t = cc_segments(t);
  if (seg_t.count(1) && ref_seg_.count(1)) {
    const auto [a0, a1] = ref_seg_.at(1);
    const auto [b0, b1] = seg_t.at(1);
    for (std::size_t j = 0; j <= std::min(a1 - a0, b1 - b0); ++j) {
      const double ch = std::abs(t.r_film[b0 + j] - ref_.r_film[a0 + j]) / ref_.r_film[a0 + j] * 100.0;
      if (!(ch <= cc1)) cc1 = ch;
    }
  }
  if (!(cc1 <= worst_cc1)) worst_cc1 = cc1;
  const auto adv = cc1_voltage_diff(t, d17);
  all_dv.insert(all_dv.end(), adv.begin(), adv.end());
  return {{"r_film_change_at_cycle_end_pct", end_change},
          {"cycle1_cc_charge_r_film_change_max_abs_pct", cc1},
          {"cycle1_cc_charge_dv_median_abs_mv", median(adv)},
          {"cycle1_cc_charge_dv_max_abs_mv", max_of(adv)}};
}

// Figures 16-17: the truth itself started with +-1 % initial conditions.
void Collector::ic_truth_figures(json& ic) {
  DatFile d16, d17;
  d16.comment("time (h), (R_film(IC) - R_film(0)) / R_film(0) (%) at the same time");
  d17.comment("time since cycle 1 CC charge start (s), V(IC) - V(0) (mV)");
  FigureData f16{"fig16", "Truth: film resistance change for +-1 % initial conditions", "time (h)",
                 "R_film change (%)", {}, "lines"};
  FigureData f17{"fig17", "Truth: voltage change for +-1 % initial conditions (cycle 1, CC charge)",
                 "time since CC charge start (s)", "V(IC) - V(0) (mV)", {}, "lines"};
  json truth_change = json::object();
  double worst_end = std::nan(""), worst_cc1 = std::nan("");
  std::vector<double> all_dv;
  for (double p : {1.0, -1.0}) {
    const CaseOut* tc = find_case(fmt::format("truth-ic{:+}", p));
    const auto t = tc ? load_truth(tc->dir / "truth") : std::nullopt;
    if (!t) continue;
    truth_change[fmt::format("{:+}", p)] = ic_truth_case(*t, d16, d17, worst_end, worst_cc1, all_dv);
    f16.curves.push_back({d16.blocks() - 1, 1, 2, fmt::format("IC {:+} %", p)});
    f17.curves.push_back({d17.blocks() - 1, 1, 2, fmt::format("IC {:+} %", p)});
  }
  if (truth_change.empty()) return;
  truth_change["cycle1_cc_charge_r_film_change_max_abs_pct"] = worst_cc1;
  truth_change["r_film_change_at_cycle_ends_max_abs_pct"] = worst_end;
  clip_y(f17, 1.5 * quantile_abs(all_dv, 0.95));
  ic["true"] = truth_change;
  d16.write(fig_dir_ / "fig16.dat");
  d17.write(fig_dir_ / "fig17.dat");
  col_.figures.push_back(f16);
  col_.figures.push_back(f17);
}

void Collector::ic_study() {
  json ic = json::object();
  ic_model_figures(ic);
  ic_truth_figures(ic);
  col_.summary["ic"] = ic;
}

}  // namespace

Collected collect(const fs::path& out_dir) {
  Collected col;
  fs::create_directories(out_dir / "figures");
  std::vector<CaseOut> cases = find_cases(out_dir);
  json& S = col.summary;
  S["cases"] = cases.size();
  // Every step planned (plan.json) or started (case.json) that did not complete, including the
  // steps of cases an interrupted run never started.
  std::set<std::pair<std::string, std::string>> steps;
  for (const auto& c : cases)
    for (const auto& s : c.spec.steps) steps.insert({c.spec.name, s.name});
  const std::vector<CaseSpec> plan = read_plan(out_dir);
  for (const auto& c : plan)
    for (const auto& s : c.steps) steps.insert({c.name, s.name});
  for (const auto& [c, s] : steps)
    if (!step_done(case_dir(out_dir, c) / s)) col.missing.push_back(c + "/" + s);
  S["planned_cases"] = plan.size();
  S["steps"] = steps.size();
  S["missing_steps"] = col.missing;

  const auto ref_it = std::find_if(cases.begin(), cases.end(), [](const CaseOut& c) { return c.spec.name == "ref"; });
  std::optional<Truth> ref;
  if (ref_it != cases.end()) ref = load_truth(ref_it->dir / "truth");
  if (!ref) {
    S["note"] = "no complete reference case (cases/ref/truth): nothing to compare against";
    return col;
  }
  S["cycles"] = ref_it->spec.cycles;
  const CaseOut ref_case = *ref_it;
  Collector c(out_dir, col, std::move(cases), ref_case, std::move(*ref));
  c.figure08();
  c.figure11();
  c.noise_study();
  c.ic_study();
  std::sort(col.figures.begin(), col.figures.end(), [](const FigureData& a, const FigureData& b) { return a.id < b.id; });
  return col;
}

}  // namespace bms::study
