// bmssim fit: a cell's parameters from its cycler data (contract: fit). The template's BPX file
// is the start; diagnosis/cell_fit moves what the data identify and keeps the rest.
#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "commands.hpp"
#include "diagnosis/cell_fit.hpp"
#include "estimation/cycler_input.hpp"
#include "io/atomic_file.hpp"
#include "io/bpx_writer.hpp"
#include "io/gnuplot.hpp"
#include "io/input_error.hpp"
#include "io/measured_profile.hpp"
#include "io/output_folder.hpp"
#include "sim/cell_catalog.hpp"

namespace bms::app {

namespace {

// Below this (A) a sample is at rest (the re-synchronisation after a long rest).
constexpr double kRestCurrentA = 0.01;
// A logging gap longer than this, at rest on both sides, restarts the model from the rest voltage
// (as a BMS re-synchronises at power-up): the data cannot say what happened in between.
constexpr double kResyncGapS = 3600.0;
// A rest this long ends near equilibrium: the model restarts from its last voltage, as a BMS
// resets its state of charge from the open-circuit voltage after a rest. Without it the model
// integrates the cycler's charge counting over many cycles and drifts with its gain mismatch
// (CS2_35 counts about 2 % more charge in than out: the cell's side reactions and the sensor).
constexpr double kResyncRestS = 1200.0;
// A charge whose last sample is this close to the upper voltage, with its last current at most this
// share of the largest (the CV phase's end current), ended full.
constexpr double kFullChargeV = 0.02;
constexpr double kFullChargeEndShare = 0.1;
// The fitted cell's voltage window: the template's unless the data go beyond it by more than this.
constexpr double kWindowMarginV = 5e-3;
// The positive OCP correction's knots unless --ocp-knots says otherwise (docs/results/aging.md:
// how this number was chosen on training cycles only).
constexpr int kDefaultOcpKnots = 8;

struct FitOptions {
  std::vector<std::string> data;
  std::string templ;
  std::string out;
  std::string train_cycles, heldout_cycles;
  std::string current_sign = "by-layout";
  std::string parameters = "all";
  int points = 20, radial = 20, search_points = 8, search_radial = 8;
  double rtol = 1e-6;
  int max_iterations = 12;
  int ocp_knots = kDefaultOcpKnots;
  std::string train_restarts = "full-charge";
  std::string score_only;           // a cell to score (no fit)
  std::vector<std::string> given;   // options given on the command line (for --score-only's checks)
  bool quiet = false;
};

// "1-5" or "1-5,8,10-12" -> cycle numbers; exit 2 naming the option.
std::set<int> parse_cycles(const std::string& text, const char* option) {
  std::set<int> out;
  std::stringstream ss(text);
  std::string part;
  while (std::getline(ss, part, ',')) {
    int a = 0, b = 0;
    char dash = 0, extra = 0;
    std::istringstream p(part);
    if ((p >> a) && !(p >> dash)) {
      b = a;
    } else {
      std::istringstream q(part);
      if (!(q >> a >> dash >> b) || dash != '-' || (q >> extra))
        throw InputError(fmt::format("{} '{}': expected cycles as A-B or A-B,C (e.g. 1-5)", option, text));
    }
    if (a < 0 || b < a || b - a > 1000000)
      throw InputError(fmt::format("{} '{}': a range A-B needs 0 <= A <= B", option, text));
    for (int c = a; c <= b; ++c) out.insert(c);
  }
  if (out.empty()) throw InputError(fmt::format("{}: empty list", option));
  return out;
}

// The template's BPX JSON and what to call it.
nlohmann::json template_json(const std::string& t, std::string& source) {
  std::filesystem::path file;
  if (t == "lco" || t == "nmc") {
    file = cell_template_file(t);
  } else if (t == "lfp") {
    // The About:Energy LFP 18650 BPX file in ../shared (read there, never copied into the repository).
    file = shared_dir() / "data/aboutenergy-lfp18650/lfp_18650_cell_BPX.json";
    if (!std::filesystem::exists(file))
      throw InputError("--template lfp: " + file.string() + " not found (set BMS_SHARED_DIR to the shared/ folder)");
  } else if (t == "paper") {
    throw InputError("--template paper: the built-in paper cell has no BPX file to write a fitted cell from; use "
                     "lco, nmc, lfp or a FILE.bpx.json");
  } else {
    file = t;
    if (!std::filesystem::is_regular_file(file))
      throw InputError("--template '" + t + "': neither lco, nmc, lfp, paper nor an existing BPX file");
  }
  source = file.string();
  std::ifstream in(file);
  nlohmann::json j;
  try {
    j = nlohmann::json::parse(in);
  } catch (const nlohmann::json::exception& e) {
    throw InputError("--template " + file.string() + ": not JSON (" + e.what() + ")");
  }
  if (!j.is_object() || !j.contains("Parameterisation"))
    throw InputError("--template " + file.string() + ": missing field 'Parameterisation'");
  return j;
}

struct Group {
  EstimateData data;
  std::string label;
};

// Where the model restarts in one group's rows: after a long logging gap at rest, at the end of a
// long rest and (full_charges) at the end of the rest after every full charge.
std::vector<std::size_t> restart_rows(const EstimateData& d, double v_max, bool full_charges) {
  std::vector<std::size_t> starts{0};
  double rest_since_s = d.t_s.front(), imax = 0.0;
  for (double i : d.current_a) imax = std::max(imax, std::abs(i));
  bool after_full = false;
  for (std::size_t k = 1; k < d.t_s.size(); ++k) {
    const bool rest = std::abs(d.current_a[k]) < kRestCurrentA, was_rest = std::abs(d.current_a[k - 1]) < kRestCurrentA;
    if (!was_rest) rest_since_s = d.t_s[k];
    // A charge that ended at the upper voltage with the CV phase's end current (a CC phase that
    // only reached the voltage, its current still high, is not full): the cell is full, a state a
    // BMS knows from its measurements alone.
    if (rest && !was_rest)
      after_full = d.current_a[k - 1] < -kRestCurrentA && d.voltage_v[k - 1] >= v_max - kFullChargeV &&
                   -d.current_a[k - 1] <= kFullChargeEndShare * imax;
    if (!rest) after_full = false;
    // The last sample of a rest (the most relaxed), or the first after a long logging gap at rest.
    const bool rest_ends = rest && was_rest && (k + 1 == d.t_s.size() || std::abs(d.current_a[k + 1]) >= kRestCurrentA);
    const bool resync = (rest && was_rest && d.t_s[k] - d.t_s[k - 1] > kResyncGapS) ||
                        (rest_ends && d.t_s[k] - rest_since_s >= kResyncRestS) ||
                        (full_charges && rest_ends && after_full);
    if (resync && k - starts.back() >= diagnosis::kMinSamples) starts.push_back(k);
  }
  if (starts.size() > 1 && d.t_s.size() - starts.back() < diagnosis::kMinSamples) starts.pop_back();
  starts.push_back(d.t_s.size());
  return starts;
}

// Rows of one group into pieces (each run from its own initial state), with the given roles;
// `want`: the roles a piece must hold to be kept (the rows of other roles stay, role 0).
void add_pieces(const Group& g, const std::vector<char>& role, double v_max, bool full_charges, char want,
                std::vector<diagnosis::FitPiece>& pieces, std::vector<std::string>& piece_labels) {
  const EstimateData& d = g.data;
  const std::vector<std::size_t> starts = restart_rows(d, v_max, full_charges);
  for (std::size_t s = 0; s + 1 < starts.size(); ++s) {
    const std::size_t a = starts[s], b = starts[s + 1];
    // A piece that holds one wanted row only (the restart row at the end of the last wanted cycle)
    // is left out: a model run needs two samples.
    std::size_t used = 0;
    for (std::size_t k = a; k < b; ++k) used += (role[k] & want) != 0;
    if (used < 2) continue;
    auto slice = [&](const std::vector<double>& v) {
      return v.empty() ? std::vector<double>{} : std::vector<double>(v.begin() + static_cast<long>(a), v.begin() + static_cast<long>(b));
    };
    diagnosis::FitPiece p;
    const std::string name = fmt::format("{} (rows {}-{})", g.label, a + 1, b);
    p.record = diagnosis::make_record(name, slice(d.t_s), slice(d.current_a), slice(d.voltage_v), slice(d.temperature_k));
    p.cycle.assign(d.cycle.begin() + static_cast<long>(a), d.cycle.begin() + static_cast<long>(b));
    p.role.assign(role.begin() + static_cast<long>(a), role.begin() + static_cast<long>(b));
    for (char& r : p.role) r = static_cast<char>(r & want);
    pieces.push_back(std::move(p));
    piece_labels.push_back(name);
  }
}

std::string command_line(const FitOptions& o) {
  std::string s = "bmssim fit";
  for (const auto& d : o.data) s += " --data " + d;
  if (!o.score_only.empty()) s += " --score-only " + o.score_only;
  if (!o.templ.empty()) s += " --template " + o.templ;
  if (!o.train_cycles.empty()) s += " --train-cycles " + o.train_cycles;
  if (!o.heldout_cycles.empty()) s += " --heldout-cycles " + o.heldout_cycles;
  if (o.parameters != "all") s += " --parameters " + o.parameters;
  if (o.current_sign != "by-layout") s += " --current-sign " + o.current_sign;
  if (o.points != 20 || o.radial != 20) s += fmt::format(" --points {} --radial {}", o.points, o.radial);
  if (o.search_points != 8 || o.search_radial != 8)
    s += fmt::format(" --search-points {} --search-radial {}", o.search_points, o.search_radial);
  if (o.rtol != 1e-6) s += fmt::format(" --rtol {}", o.rtol);
  if (o.max_iterations != 12) s += fmt::format(" --max-iterations {}", o.max_iterations);
  if (o.ocp_knots != kDefaultOcpKnots) s += fmt::format(" --ocp-knots {}", o.ocp_knots);
  if (o.train_restarts != "full-charge") s += " --train-restarts " + o.train_restarts;
  return s + " --out " + o.out;
}

// The held-out cycles' voltage, one panel per cycle (hours since the cycle's first row).
std::string cycle_panels_gp(const std::vector<diagnosis::CycleScore>& cycles, const char* name) {
  std::vector<int> held;
  for (const auto& c : cycles)
    if (c.role == diagnosis::kRoleHeldOut) held.push_back(c.cycle);
  if (held.empty()) return "";
  const int cols = std::max(1, static_cast<int>(std::ceil(std::sqrt(static_cast<double>(held.size())))));
  const int rows = (static_cast<int>(held.size()) + cols - 1) / cols;
  std::string gp = fmt::format(
      "set output '{}.tmp'\nset autoscale\nset terminal pngcairo size {},{} noenhanced\nset multiplot layout {},{} title "
      "'Held-out cycles: measured (black) and fitted (red) voltage; each piece restarted from the rest after a full "
      "charge'\nunset key\nset xlabel 'h since the cycle began'; set ylabel 'V'\n",
      name, 380 * cols, 300 * rows + 60, rows, cols);
  for (int c : held) {
    const auto it = std::find_if(cycles.begin(), cycles.end(), [&](const auto& x) { return x.cycle == c; });
    gp += fmt::format(
        "set title 'cycle {}: {:.1f} mV, {}/{} rows'\n"
        "plot 'fit.csv' skip 1 using 12:($4=={}&&$5==2?$7:1/0) with lines lw 2 lc rgb 'black', "
        "'' skip 1 using 12:($4=={}&&$5==2?$9:1/0) with lines lc rgb 'red'\n",
        c, it->rmse_mv, it->scored, it->samples, c, c);
  }
  return gp + "unset multiplot\nset autoscale\nset terminal pngcairo size 1400,800 noenhanced\nset key outside bottom center horizontal\n";
}

std::vector<std::string> plot(const std::filesystem::path& dir, const std::vector<diagnosis::CycleScore>& cycles,
                              std::string& problem) {
  std::vector<std::string> names = {"voltage_train.png", "voltage_heldout.png", "residual.png", "rmse_cycles.png"};
  std::string gp =
      "# Made by bmssim fit; run in this folder: gnuplot plots.gp\n"
      "set datafile separator ','\nset terminal pngcairo size 1400,800 noenhanced\nset grid\n"
      "set key outside bottom center horizontal\n";
  // fit.csv: 1 piece, 2 t_s, 3 t_h (record hours), 4 cycle, 5 role, 6 current_a, 7 voltage_meas_v,
  // 8 voltage_template_v, 9 voltage_fitted_v, 10 residual_template_mv, 11 residual_fitted_mv,
  // 12 t_cycle_h, 13 scored (NaN model voltage: a row the model did not reach)
  const char* roles[] = {"train", "held out"};
  for (int r = 0; r < 2; ++r)
    gp += fmt::format(
        "set output '{0}.tmp'\nset title 'Measured and model voltage, {1} cycles (model = DFN on the measured current, "
        "restarted after each full charge)'\n"
        "set xlabel 'time (h, gaps removed)'; set ylabel 'voltage (V)'\n"
        "plot 'fit.csv' skip 1 using 3:($5=={2}?$7:1/0) with lines lw 2 lc rgb 'black' title 'measured', "
        "'' skip 1 using 3:($5=={2}?$8:1/0) with lines lc rgb '#999999' title 'template', "
        "'' skip 1 using 3:($5=={2}?$9:1/0) with lines lc rgb 'red' title 'fitted'\n",
        names[static_cast<std::size_t>(r)], roles[r], r + 1);
  gp += fmt::format(
      "set output '{0}.tmp'\nset title 'Residual (model - measured), training then held-out rows'\n"
      "set xlabel 'time (h, gaps removed)'; set ylabel 'residual (mV)'\n"
      "plot 'fit.csv' skip 1 using 3:($5==1?$11:1/0) with points pt 7 ps 0.3 lc rgb 'blue' title 'fitted, training', "
      "'' skip 1 using 3:($5==2?$11:1/0) with points pt 7 ps 0.3 lc rgb 'red' title 'fitted, held out', "
      "'' skip 1 using 3:10 with points pt 7 ps 0.2 lc rgb '#aaaaaa' title 'template'\n",
      names[2]);
  // cycles.csv: 1 cycle, 2 role, 3 samples, 4 scored, 5 rmse_mv, 6 mean_mv, 7 max_abs_mv, 8 rmse_template_mv
  gp += fmt::format(
      "set output '{0}.tmp'\nset title 'Voltage RMSE per cycle (rows the model reached)'\n"
      "set xlabel 'cycle'; set ylabel 'RMSE (mV)'; set yrange [0:*]; set style fill solid 0.6; set boxwidth 0.7\n"
      "plot 'cycles.csv' skip 1 using 1:(strcol(2) eq 'train'?$5:1/0) with boxes lc rgb 'blue' title 'fitted, training', "
      "'' skip 1 using 1:(strcol(2) eq 'heldout'?$5:1/0) with boxes lc rgb 'red' title 'fitted, held out', "
      "'' skip 1 using 1:8 with linespoints lc rgb '#999999' title 'template'\n",
      names[3]);
  const std::string panels = cycle_panels_gp(cycles, "voltage_heldout_cycles.png");
  if (!panels.empty()) gp += panels, names.emplace_back("voltage_heldout_cycles.png");
  AtomicFileWriter script(dir / "plots.gp");
  script.append(gp);
  script.commit();
  GnuplotOptions g;
  g.working_dir = dir;
  return commit_plots(dir, names, run_gnuplot("plots.gp", g), problem);
}

// --parameters: "all", or names fit_parameter_names() knows.
void parse_parameter_list(const std::string& list, diagnosis::CellFitSettings& settings) {
  if (list == "all") return;
  const auto known = diagnosis::fit_parameter_names();
  std::stringstream ss(list);
  std::string n;
  while (std::getline(ss, n, ','))
    if (std::find(known.begin(), known.end(), n) == known.end())
      throw InputError(fmt::format("--parameters: unknown name '{}'; use all or a comma-separated list of {}", n,
                                   fmt::join(known, ", ")));
    else
      settings.only.push_back(n);
}

// The records: one group (split by cycles) or one per --data; each must carry current.
std::vector<Group> read_groups(const FitOptions& o, CurrentSign sign, bool by_cycles) {
  std::vector<Group> groups;
  if (by_cycles) {
    groups.push_back({read_estimate_input(o.data, sign).data, fmt::format("{}", fmt::join(o.data, ", "))});
  } else {
    for (const auto& d : o.data) groups.push_back({read_estimate_input({d}, sign).data, d});
  }
  for (const auto& g : groups) {
    double imax = 0;
    for (double i : g.data.current_a) imax = std::max(imax, std::abs(i));
    if (!(imax > kRestCurrentA))
      throw InputError(fmt::format("--data {}: no current flows in the record (|I| <= {} A throughout): nothing to "
                                   "fit; give cycler data with charges and discharges",
                                   g.label, kRestCurrentA));
  }
  return groups;
}

// Roles by cycles of the one record: the training and held-out cycles (default: the first half
// fitted, the rest held out).
std::vector<char> roles_by_cycles(const FitOptions& o, const Group& group, std::string& split_note) {
  const auto& cyc = group.data.cycle;
  std::set<int> all(cyc.begin(), cyc.end()), train, held;
  if (!o.train_cycles.empty()) {
    train = parse_cycles(o.train_cycles, "--train-cycles");
  } else {
    std::size_t n = 0;
    for (int c : all)
      if (n++ < (all.size() + 1) / 2) train.insert(c);
  }
  if (!o.heldout_cycles.empty()) {
    held = parse_cycles(o.heldout_cycles, "--heldout-cycles");
  } else {
    for (int c : all)
      if (!train.count(c)) held.insert(c);
  }
  std::vector<char> role(cyc.size(), 0);
  std::size_t nt = 0;
  for (std::size_t k = 0; k < cyc.size(); ++k) {
    if (train.count(cyc[k])) role[k] = diagnosis::kRoleTrain, ++nt;
    else if (held.count(cyc[k])) role[k] = diagnosis::kRoleHeldOut;
  }
  if (nt < diagnosis::kMinSamples)
    throw InputError(fmt::format("--train-cycles: {} training samples in cycles {} of the data (cycles {}..{}); "
                                 "need at least {}",
                                 nt, o.train_cycles.empty() ? "(default)" : o.train_cycles, *all.begin(),
                                 *all.rbegin(), diagnosis::kMinSamples));
  split_note = fmt::format("cycles {} fitted, cycles {} held out", fmt::join(train, ","),
                           held.empty() ? std::string("(none)") : fmt::format("{}", fmt::join(held, ",")));
  return role;
}

// The fitted cell's voltage window (the template's, widened to the training data's) and the
// largest charge one discharge of the training rows delivered (current > 0 throughout).
void window_and_capacity(const std::vector<Group>& groups, const std::vector<std::vector<char>>& roles,
                         const CellParameters& template_cell, diagnosis::CellFitSettings& settings) {
  double vmin = HUGE_VAL, vmax = -HUGE_VAL;
  for (std::size_t g = 0; g < groups.size(); ++g)
    for (std::size_t k = 0; k < roles[g].size(); ++k)
      if (roles[g][k] == diagnosis::kRoleTrain)
        vmin = std::min(vmin, groups[g].data.voltage_v[k]), vmax = std::max(vmax, groups[g].data.voltage_v[k]);
  settings.v_max = vmax > template_cell.upper_voltage_v + kWindowMarginV ? std::round(vmax * 100) / 100
                                                                          : template_cell.upper_voltage_v;
  settings.v_min = vmin < template_cell.lower_voltage_v - kWindowMarginV ? std::round(vmin * 100) / 100
                                                                          : template_cell.lower_voltage_v;
  for (std::size_t g = 0; g < groups.size(); ++g) {
    const auto& d = groups[g].data;
    double q = 0;
    for (std::size_t k = 1; k < d.t_s.size(); ++k) {
      const bool on = roles[g][k] == diagnosis::kRoleTrain && d.current_a[k] > kRestCurrentA &&
                      d.current_a[k - 1] > kRestCurrentA;
      q = on ? q + 0.5 * (d.current_a[k] + d.current_a[k - 1]) * (d.t_s[k] - d.t_s[k - 1]) / 3600.0 : 0.0;
      settings.measured_capacity_ah = std::max(settings.measured_capacity_ah, q);
    }
  }
}

// The fitted cell, with a header that says where it came from.
void write_cell(const OutputFolder& folder, const FitOptions& o, const nlohmann::json& tmpl,
                const std::string& template_source, const std::string& split_note,
                const diagnosis::CellFitResult& fit) {
  nlohmann::json cell = nlohmann::json::parse(fit.bpx_text);
  std::string fitted_list;
  for (const auto& p : fit.parameters)
    if (p.fitted) fitted_list += (fitted_list.empty() ? "" : ", ") + p.name;
  write_bpx_cell(
      folder.staging() / "cell.bpx.json", std::move(cell),
      fmt::format("Fitted by bmssim fit from template '{}'", o.templ),
      fmt::format("Fitted to measured cycler data by `{}` ({}). Fitted: {}; voltage window and stoichiometry windows "
                  "from the electrode balance at the data's window; every other value is the template's ({}). "
                  "Template description: {}",
                  command_line(o), split_note, fitted_list.empty() ? "nothing" : fitted_list, template_source,
                  tmpl.value("/Header/Description"_json_pointer, std::string("(none)"))));
}

// fit.csv (every scored row; the model voltage NaN where the model did not reach the row) and
// cycles.csv (per cycle).
void write_fit_csv(const OutputFolder& folder, const std::vector<diagnosis::FitPiece>& pieces,
                   const diagnosis::CellScore& fitted, const diagnosis::CellScore* templ) {
  AtomicFileWriter w(folder.staging() / "fit.csv");
  w.append("piece,t_s,t_h,cycle,role,current_a,voltage_meas_v,voltage_template_v,voltage_fitted_v,"
           "residual_template_mv,residual_fitted_mv,t_cycle_h,scored\n");
  double t_h = 0;
  std::map<int, double> cycle_start_s;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  for (std::size_t p = 0; p < pieces.size(); ++p) {
    const auto& r = pieces[p].record;
    for (std::size_t k = 0; k < r.t_s.size(); ++k) {
      if (k > 0) t_h += std::min(r.t_s[k] - r.t_s[k - 1], 600.0) / 3600.0;
      if (!pieces[p].role[k]) continue;
      const double vf = fitted.voltage_v[p][k], vt = templ ? templ->voltage_v[p][k] : nan;
      const double t0 = cycle_start_s.emplace(pieces[p].cycle[k], r.t_s[k]).first->second;
      w.append(fmt::format("{},{:.3f},{:.5f},{},{},{:.6g},{:.6f},{:.6f},{:.6f},{:.4f},{:.4f},{:.5f},{}\n", p, r.t_s[k],
                           t_h, pieces[p].cycle[k], static_cast<int>(pieces[p].role[k]), r.current_a[k], r.voltage_v[k],
                           vt, vf, 1e3 * (vt - r.voltage_v[k]), 1e3 * (vf - r.voltage_v[k]),
                           (r.t_s[k] - t0) / 3600.0, std::isfinite(vf) ? 1 : 0));
    }
  }
  w.commit();
  AtomicFileWriter c(folder.staging() / "cycles.csv");
  c.append("cycle,role,samples,scored,rmse_mv,mean_mv,max_abs_mv,rmse_template_mv\n");
  for (std::size_t i = 0; i < fitted.cycles.size(); ++i) {
    const auto& x = fitted.cycles[i];
    c.append(fmt::format("{},{},{},{},{:.4f},{:.4f},{:.4f},{:.4f}\n", x.cycle,
                         x.role == diagnosis::kRoleTrain ? "train" : "heldout", x.samples, x.scored, x.rmse_mv,
                         x.mean_mv, x.max_abs_mv, templ ? templ->cycles[i].rmse_mv : nan));
  }
  c.commit();
}

nlohmann::json num(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

// The score's per-cycle numbers, coverage and where the model stopped.
nlohmann::json score_json(const diagnosis::CellScore& f, const diagnosis::CellScore* templ) {
  nlohmann::json cycles = nlohmann::json::array(), stops = nlohmann::json::array();
  for (std::size_t i = 0; i < f.cycles.size(); ++i) {
    const auto& c = f.cycles[i];
    cycles.push_back({{"cycle", c.cycle}, {"role", c.role == diagnosis::kRoleTrain ? "train" : "heldout"},
                      {"samples", c.samples}, {"scored", c.scored}, {"rmse_mv", num(c.rmse_mv)},
                      {"mean_mv", num(c.mean_mv)}, {"max_abs_mv", num(c.max_abs_mv)},
                      {"rmse_template_mv", templ ? num(templ->cycles[i].rmse_mv) : nlohmann::json(nullptr)}});
  }
  for (const auto& s : f.stops)
    stops.push_back({{"piece", s.piece + 1}, {"row", s.row + 1}, {"rows", s.rows}, {"cycle", s.cycle},
                     {"t_s", s.t_s}, {"why", s.why}});
  auto share = [](std::size_t a, std::size_t b) { return b ? nlohmann::json(static_cast<double>(a) / static_cast<double>(b)) : nlohmann::json(nullptr); };
  return {{"cycles", cycles},
          {"stops", stops},
          {"train_samples", f.train_samples},
          {"train_scored_samples", f.train_scored},
          {"train_coverage", share(f.train_scored, f.train_samples)},
          {"heldout_samples", f.heldout_samples},
          {"heldout_scored_samples", f.heldout_scored},
          {"heldout_coverage", share(f.heldout_scored, f.heldout_samples)},
          {"piece_initial_states", f.initial_states}};
}

nlohmann::json parameters_json(const diagnosis::CellFitResult& fit) {
  nlohmann::json params = nlohmann::json::object();
  for (const auto& p : fit.parameters) {
    nlohmann::json e = {{"value", p.value}, {"sd", num(p.sd)}, {"template", num(p.template_value)},
                        {"fitted", p.fitted}, {"unit", p.unit}, {"meaning", p.meaning}};
    if (!p.note.empty()) e["note"] = p.note;
    params[p.name] = e;
  }
  return params;
}

constexpr char kBothRoles = diagnosis::kRoleTrain | diagnosis::kRoleHeldOut;

std::string restarts_text(bool full_charges) {
  return std::string(full_charges ? "at the end of the rest after every full charge (a charge that ended at the upper "
                                    "voltage with the CV phase's end current), "
                                  : "") +
         "after a logging gap over 1 h at rest and at the end of a rest of 20 min or more; each piece starts from the "
         "measured voltage at its first row through the cell's open-circuit curve (piece_initial_states)";
}

nlohmann::json summary_json(const FitOptions& o, const std::string& template_source, const std::string& split_note,
                            const diagnosis::CellFitResult& fit, const std::vector<std::string>& labels,
                            const std::vector<std::string>& search_labels, const std::vector<std::string>& pngs,
                            double wall_s) {
  nlohmann::json j = {
      {"command", command_line(o)},
      {"template", o.templ},
      {"template_file", template_source},
      {"split", split_note},
      {"rmse_train_mv", num(fit.rmse_train_mv)},
      {"rmse_heldout_mv", num(fit.rmse_heldout_mv)},
      {"max_abs_heldout_mv", num(fit.max_abs_heldout_mv)},
      {"rmse_template_train_mv", num(fit.rmse_template_train_mv)},
      {"rmse_template_heldout_mv", num(fit.rmse_template_heldout_mv)},
      {"rmse_objective_mv", num(fit.rmse_objective_mv)},
      {"residual_sd_mv", fit.residual_sd_mv},
      {"parameters", parameters_json(fit)},
      {"derived", fit.derived},
      {"restarts", {{"score", restarts_text(true)}, {"search", restarts_text(o.train_restarts == "full-charge")},
                    {"train_restarts", o.train_restarts}}},
      {"pieces", labels},
      {"search_pieces", search_labels},
      {"model_runs", fit.evaluations},
      {"iterations", fit.iterations},
      {"search_mesh", {o.search_points, o.search_radial}},
      {"final_mesh", {o.points, o.radial}},
      {"rtol", o.rtol},
      {"sd_method",
       "J^T J inverse times the residual variance at the optimum (J by forward differences on the search mesh); "
       "the residual is treated as independent noise, so with model error the sd is a lower bound"},
      {"notes", fit.notes},
      {"plots", pngs},
      {"wall_s", wall_s}};
  j.update(score_json(fit.fitted, &fit.templ));
  return j;
}

// The records, their roles and the split: what every run reads before its first model run.
struct Prepared {
  std::vector<Group> groups;
  std::vector<std::vector<char>> roles;
  std::string split_note;
};

Prepared prepare(const FitOptions& o) {
  const CurrentSign sign = current_sign_option(o.current_sign);
  for (const auto& d : o.data)
    if (!std::filesystem::exists(d)) throw InputError("--data " + d + ": no such file or folder");
  const bool by_cycles = !o.train_cycles.empty() || o.data.size() == 1;
  if (!o.heldout_cycles.empty() && !by_cycles)
    throw InputError("--heldout-cycles: only with --train-cycles (several --data without it: the first is fitted, "
                     "the others held out)");
  Prepared p;
  p.groups = read_groups(o, sign, by_cycles);
  // Roles: by cycles (one record), or the first --data fitted and the others held out.
  if (by_cycles) {
    p.roles.push_back(roles_by_cycles(o, p.groups[0], p.split_note));
  } else {
    for (std::size_t g = 0; g < p.groups.size(); ++g)
      p.roles.emplace_back(p.groups[g].data.t_s.size(), g == 0 ? diagnosis::kRoleTrain : diagnosis::kRoleHeldOut);
    p.split_note = fmt::format("{} fitted, the other --data held out", p.groups[0].label);
  }
  return p;
}

void make_pieces(const Prepared& d, double v_max, bool full_charges, char want,
                 std::vector<diagnosis::FitPiece>& pieces, std::vector<std::string>& labels) {
  for (std::size_t g = 0; g < d.groups.size(); ++g)
    add_pieces(d.groups[g], d.roles[g], v_max, full_charges, want, pieces, labels);
}

void write_summary(const OutputFolder& folder, const nlohmann::json& j) {
  AtomicFileWriter w(folder.staging() / "summary.json");
  w.append(j.dump(2) + "\n");
  w.commit();
}

void check_fit_options(const FitOptions& o, diagnosis::CellFitSettings& settings) {
  if (o.templ.empty()) throw InputError("--template: required (or --score-only CELL to score a cell without fitting)");
  if (o.train_restarts != "full-charge" && o.train_restarts != "rests")
    throw InputError("--train-restarts '" + o.train_restarts + "': full-charge or rests");
  parse_parameter_list(o.parameters, settings);
  if (o.ocp_knots == 1 || o.ocp_knots < 0 || o.ocp_knots > diagnosis::kMaxOcpKnots)
    throw InputError(fmt::format("--ocp-knots {}: must be 0 (no open-circuit correction) or 2..{}", o.ocp_knots,
                                 diagnosis::kMaxOcpKnots));
  for (const auto& n : settings.only) {
    static const std::string kOneKnot = "ocp_correction_";  // cell_fit's knot names: ocp_correction_N
    const bool knot = n.rfind("ocp_correction", 0) == 0;
    const int index = knot && n.size() > kOneKnot.size() ? std::atoi(n.c_str() + kOneKnot.size()) : 0;
    if (knot && (o.ocp_knots == 0 || index > o.ocp_knots))
      throw InputError(fmt::format("--parameters {}: --ocp-knots {} has no such knot (give --ocp-knots 2..{})", n,
                                   o.ocp_knots, diagnosis::kMaxOcpKnots));
  }
  settings.ocp_knots = o.ocp_knots;
}

void report(const char* what, const diagnosis::CellScore& f, double wall_s, const std::string& out) {
  std::fprintf(stderr,
               "fit: %s: RMSE train %.2f mV (%zu of %zu rows scored), held out %.2f mV (%zu of %zu rows scored, "
               "coverage %.3f); %zu early stop(s); %.1f s -> %s\n",
               what, f.rmse_train_mv, f.train_scored, f.train_samples, f.rmse_heldout_mv, f.heldout_scored,
               f.heldout_samples, f.heldout_samples ? static_cast<double>(f.heldout_scored) / static_cast<double>(f.heldout_samples) : 0.0,
               f.stops.size(), wall_s, out.c_str());
}

int run_fit(const FitOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  auto log = [q = o.quiet](const std::string& s) {
    if (!q) std::fprintf(stderr, "fit: %s\n", s.c_str());
  };
  // Everything that can be refused is checked before the first model run.
  if (!(o.rtol > 0.0 && o.rtol < 1e-2)) throw InputError("--rtol: must be in (0, 0.01)");
  diagnosis::CellFitSettings settings;
  check_fit_options(o, settings);
  std::string template_source;
  nlohmann::json tmpl = template_json(o.templ, template_source);
  const CellParameters template_cell = load_cell(o.templ == "lfp" ? template_source : o.templ);
  for (const auto& d : o.data)
    if (!std::filesystem::exists(d)) throw InputError("--data " + d + ": no such file or folder");
  OutputFolder folder(o.out);
  const Prepared d = prepare(o);
  window_and_capacity(d.groups, d.roles, template_cell, settings);
  std::vector<diagnosis::FitPiece> search_pieces, score_pieces;
  std::vector<std::string> search_labels, labels;
  make_pieces(d, settings.v_max, o.train_restarts == "full-charge", diagnosis::kRoleTrain, search_pieces, search_labels);
  make_pieces(d, settings.v_max, true, kBothRoles, score_pieces, labels);
  settings.search_mesh = {o.search_points, o.search_points, o.search_points, o.search_radial};
  settings.final_mesh = {o.points, o.points, o.points, o.radial};
  settings.rtol = o.rtol;
  settings.max_iterations = o.max_iterations;
  log(fmt::format("template {} ({}); {}; {} search piece(s), {} scoring piece(s); voltage window {:.3f}-{:.3f} V",
                  o.templ, template_source, d.split_note, search_pieces.size(), score_pieces.size(), settings.v_min,
                  settings.v_max));

  const diagnosis::CellFitResult fit = diagnosis::fit_cell(tmpl, o.templ, search_pieces, score_pieces, settings, log);
  write_cell(folder, o, tmpl, template_source, d.split_note, fit);
  write_fit_csv(folder, score_pieces, fit.fitted, &fit.templ);
  std::string plot_problem;
  const auto pngs = plot(folder.staging(), fit.fitted.cycles, plot_problem);
  if (!plot_problem.empty()) std::fprintf(stderr, "fit: warning: no plots: %s\n", plot_problem.c_str());
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  write_summary(folder, summary_json(o, template_source, d.split_note, fit, labels, search_labels, pngs, wall_s));
  folder.commit();
  report("fitted cell", fit.fitted, wall_s, o.out);
  std::fprintf(stderr, "fit: template: RMSE train %.2f mV, held out %.2f mV; %d runs\n", fit.rmse_template_train_mv,
               fit.rmse_template_heldout_mv, fit.evaluations);
  return 0;
}

// --score-only CELL: the cell as it is, scored on the rows of the split (no search).
int run_score_only(const FitOptions& o) {
  const auto t0 = std::chrono::steady_clock::now();
  for (const char* opt : {"--template", "--parameters", "--ocp-knots", "--search-points", "--search-radial",
                          "--max-iterations", "--train-restarts"})
    if (std::find(o.given.begin(), o.given.end(), opt) != o.given.end())
      throw InputError(fmt::format("{}: not used with --score-only (it scores the given cell as it is, no fit)", opt));
  if (!(o.rtol > 0.0 && o.rtol < 1e-2)) throw InputError("--rtol: must be in (0, 0.01)");
  if (!std::filesystem::is_regular_file(o.score_only))
    throw InputError("--score-only " + o.score_only + ": no such file (give a cell's BPX file, e.g. a fit's cell.bpx.json)");
  CellParameters cell;
  try {
    cell = load_cell(o.score_only);
  } catch (const InputError& e) {
    throw InputError(std::string("--score-only: ") + e.what());
  }
  OutputFolder folder(o.out);
  const Prepared d = prepare(o);
  std::vector<diagnosis::FitPiece> pieces;
  std::vector<std::string> labels;
  make_pieces(d, cell.upper_voltage_v, true, kBothRoles, pieces, labels);
  if (!o.quiet)
    std::fprintf(stderr, "fit: scoring %s on %s; %zu piece(s)\n", o.score_only.c_str(), d.split_note.c_str(),
                 pieces.size());
  const diagnosis::CellScore sc =
      diagnosis::score_cell(cell, pieces, {o.points, o.points, o.points, o.radial}, o.rtol);
  write_fit_csv(folder, pieces, sc, nullptr);
  std::string plot_problem;
  const auto pngs = plot(folder.staging(), sc.cycles, plot_problem);
  if (!plot_problem.empty()) std::fprintf(stderr, "fit: warning: no plots: %s\n", plot_problem.c_str());
  const double wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
  nlohmann::json notes = nlohmann::json::array();
  for (const auto& st : sc.stops)
    notes.push_back(fmt::format("the model stopped at row {} of {} of piece {} (cycle {}, t = {:.1f} s): {}; the rows "
                                "after it are not scored",
                                st.row + 1, st.rows, st.piece + 1, st.cycle, st.t_s, st.why));
  nlohmann::json j = {{"command", command_line(o)}, {"score_only", o.score_only}, {"split", d.split_note},
                      {"rmse_train_mv", num(sc.rmse_train_mv)}, {"rmse_heldout_mv", num(sc.rmse_heldout_mv)},
                      {"max_abs_heldout_mv", num(sc.max_abs_heldout_mv)}, {"restarts", {{"score", restarts_text(true)}}},
                      {"pieces", labels}, {"final_mesh", {o.points, o.radial}}, {"rtol", o.rtol}, {"notes", notes},
                      {"plots", pngs}, {"wall_s", wall_s}};
  j.update(score_json(sc, nullptr));
  write_summary(folder, j);
  folder.commit();
  report("scored cell", sc, wall_s, o.out);
  return 0;
}

}  // namespace

Runner add_fit(CLI::App& app) {
  auto* sub = app.add_subcommand(
      "fit",
      "Fit a cell's parameters to its cycler data, starting from a template: the electrode balance (capacity and "
      "stoichiometry windows), series resistance, solid diffusivities, kinetics, electrolyte conductivity and (by "
      "default) a correction to the positive electrode's open-circuit potential, each only where the data identify "
      "it (with its standard error); the rest keep the template's values. Writes cell.bpx.json (for any --cell), "
      "summary.json, fit.csv and plots");
  auto o = std::make_shared<FitOptions>();
  sub->add_option("--data", o->data,
                  "Measured data: a cycler export (Arbin, Maccor, Neware, BioLogic, NASA), a folder of one cell's "
                  "exports, truth.csv or any CSV with time, current and voltage columns. Repeatable: with "
                  "--train-cycles (or one --data) the files are one record split by cycles; otherwise the first is "
                  "fitted and the others held out")
      ->required();
  sub->add_option("--template", o->templ,
                  "lco | nmc | lfp (the About:Energy LFP cell read from ../shared) | FILE.bpx.json (paper has no BPX "
                  "file to write from and is refused); required unless --score-only");
  sub->add_option("--score-only", o->score_only,
                  "A cell's BPX file (e.g. a fit's cell.bpx.json) scored as it is on the training and held-out rows "
                  "(the same pieces, restarts and per-cycle numbers as a fit's final score), no fit: summary.json, "
                  "fit.csv, cycles.csv and plots");
  sub->add_option("--train-restarts", o->train_restarts,
                  "full-charge: the search restarts the model where the score does (at the rest after every full "
                  "charge, after long rests and logging gaps); rests: only after long rests and logging gaps. The "
                  "score always restarts after every full charge")
      ->capture_default_str();
  sub->add_option("--out", o->out, "Output folder (cell.bpx.json, summary.json, fit.csv, PNG plots)")->required();
  sub->add_option("--train-cycles", o->train_cycles,
                  "Cycles fitted, e.g. 1-5 (default: the first half of the record's cycles, rounded up)");
  sub->add_option("--heldout-cycles", o->heldout_cycles,
                  "Cycles scored, e.g. 6-20 (default: every cycle not fitted)");
  sub->add_option("--parameters", o->parameters,
                  "all, or a comma-separated list of the parameters that may be fitted (names as in summary.json)")
      ->capture_default_str();
  sub->add_option("--current-sign", o->current_sign,
                  "discharge-positive | charge-positive (default: by the file's layout)")
      ->capture_default_str();
  sub->add_option("--points", o->points, "Scoring mesh: finite volumes per region")->capture_default_str()->check(CLI::Range(2, 400));
  sub->add_option("--radial", o->radial, "Scoring mesh: finite volumes per particle")->capture_default_str()->check(CLI::Range(3, 400));
  sub->add_option("--search-points", o->search_points, "Fit mesh: finite volumes per region")
      ->capture_default_str()->check(CLI::Range(2, 400));
  sub->add_option("--search-radial", o->search_radial, "Fit mesh: finite volumes per particle")
      ->capture_default_str()->check(CLI::Range(3, 400));
  sub->add_option("--rtol", o->rtol, "IDA relative tolerance")->capture_default_str();
  sub->add_option("--max-iterations", o->max_iterations, "Levenberg-Marquardt iterations per round")
      ->capture_default_str()->check(CLI::Range(1, 200));
  sub->add_option("--ocp-knots", o->ocp_knots,
                  "Knots of the additive correction to the positive electrode's OCP (piecewise linear in its "
                  "stoichiometry, evenly over the template's window; each knot a parameter in volts, in --parameters "
                  "as ocp_correction or ocp_correction_N): 0 = the template's OCP as it is, or 2..8. On by default: "
                  "a template's OCP is another cell's and its error does not fit into any resistance")
      ->capture_default_str();
  sub->add_flag("--quiet", o->quiet, "No progress output");
  sub->footer(
      "Exit codes: 0 fitted cell written, 1 runtime failure, 2 bad input.\n"
      "Example: bmssim fit --data ../shared/data/calce-cs2-35 --template lco --train-cycles 1-5 "
      "--heldout-cycles 6-20 --out out/fit\n"
      "         bmssim simulate --cell out/fit/cell.bpx.json --cycles 1 --out out/fit-sim");
  return [o, sub]() {
    for (const char* opt : {"--template", "--parameters", "--ocp-knots", "--search-points", "--search-radial",
                            "--max-iterations", "--train-restarts"})
      if (sub->count(opt) > 0) o->given.emplace_back(opt);
    return o->score_only.empty() ? run_fit(*o) : run_score_only(*o);
  };
}

}  // namespace bms::app
