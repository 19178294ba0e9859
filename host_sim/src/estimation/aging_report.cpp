#include "estimation/aging_report.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <system_error>

#include "io/atomic_file.hpp"
#include "io/csv_table.hpp"
#include "io/gnuplot.hpp"

namespace bms {

namespace {

constexpr double kPartialCycleShare = 0.05;

nlohmann::json num(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

}  // namespace

LineFit fit_line(const std::vector<double>& x, const std::vector<double>& y) {
  LineFit f;
  double sx = 0, sy = 0;
  for (std::size_t i = 0; i < x.size(); ++i)
    if (std::isfinite(x[i]) && std::isfinite(y[i])) {
      sx += x[i];
      sy += y[i];
      ++f.n;
    }
  if (f.n < 3) return f;
  const double mx = sx / static_cast<double>(f.n), my = sy / static_cast<double>(f.n);
  double sxx = 0, syy = 0, sxy = 0;
  for (std::size_t i = 0; i < x.size(); ++i)
    if (std::isfinite(x[i]) && std::isfinite(y[i])) {
      sxx += (x[i] - mx) * (x[i] - mx);
      syy += (y[i] - my) * (y[i] - my);
      sxy += (x[i] - mx) * (y[i] - my);
    }
  if (sxx > 0) {
    f.slope = sxy / sxx;
    f.intercept = my - f.slope * mx;
  }
  if (sxx > 0 && syy > 0) f.pearson = sxy / std::sqrt(sxx * syy);
  return f;
}

namespace {

// The SoH errors over the rows with a capacity and the resistance growths' lines on the IR growth.
void score(AgingComparison& a) {
  std::vector<double> ir, film, step, dstep, onset;
  double sum = 0.0, worst = 0.0, sum_counted = 0.0;
  std::size_t n_est = 0, n_counted = 0;
  for (const AgingRow& r : a.rows) {
    // A charge with no capacity (not a whole charge, counted) is not scored.
    if (const double e = std::abs(r.soh_est - r.soh_meas) * 100.0; std::isfinite(e)) {
      sum += e;
      worst = std::max(worst, e);
      ++n_est;
    }
    if (const double e = std::abs(r.soh_counted - r.soh_meas) * 100.0; std::isfinite(e) && r.counted_complete) {
      sum_counted += e;
      ++n_counted;
    }
    ir.push_back(r.ir_growth_meas_ohm);
    film.push_back(r.r_growth_est_ohm);
    step.push_back(r.r_step_growth_ohm);
    dstep.push_back(r.r_discharge_step_growth_ohm);
    onset.push_back(r.r_discharge_onset_growth_ohm);
  }
  a.cycles_scored = n_est;
  if (n_est > 0) {
    a.soh_mae_pp = sum / static_cast<double>(n_est);
    a.soh_max_abs_pp = worst;
  }
  if (n_counted > 0) a.soh_counted_mae_pp = sum_counted / static_cast<double>(n_counted);
  a.film_vs_ir = fit_line(ir, film);
  a.step_vs_ir = fit_line(ir, step);
  a.discharge_step_vs_ir = fit_line(ir, dstep);
  a.discharge_onset_vs_ir = fit_line(ir, onset);
}

}  // namespace

AgingComparison compare_aging(const std::vector<ChargeReport>& charges, const std::vector<CyclerCycleStat>& cycler) {
  AgingComparison a;
  double max_dis = 0.0;
  std::map<int, const CyclerCycleStat*> by_cycle;
  for (const auto& s : cycler) {
    max_dis = std::max(max_dis, s.discharge_ah);
    by_cycle[s.cycle] = &s;
  }
  const ChargeReport* ref = nullptr;
  const ChargeReport* ref_cap = nullptr;
  const CyclerCycleStat* ref_meas = nullptr;
  double ref_ir = std::nan("");
  double ref_step = std::nan(""), ref_dstep = std::nan(""), ref_onset = std::nan("");
  for (const ChargeReport& c : charges) {
    const auto it = by_cycle.find(c.cycle);
    if (it == by_cycle.end() || !(it->second->discharge_ah >= kPartialCycleShare * max_dis)) continue;
    const CyclerCycleStat& m = *it->second;
    if (ref == nullptr) ref = &c;
    // The capacity's reference is the first charge with one (a whole charge where counted);
    // before it, and in a record with none (another cell's voltage limits), SoH stays empty.
    if (ref_cap == nullptr && std::isfinite(c.capacity_ah)) {
      ref_cap = &c;
      ref_meas = &m;
    }
    if (std::isnan(ref_ir) && std::isfinite(m.internal_resistance_ohm)) ref_ir = m.internal_resistance_ohm;
    if (std::isnan(ref_step) && std::isfinite(c.r_step_ohm)) ref_step = c.r_step_ohm;
    if (std::isnan(ref_dstep) && std::isfinite(c.r_discharge_step_ohm)) ref_dstep = c.r_discharge_step_ohm;
    if (std::isnan(ref_onset) && std::isfinite(c.r_discharge_onset_ohm)) ref_onset = c.r_discharge_onset_ohm;
    AgingRow r{};
    r.cycle = c.cycle;
    r.capacity_est_ah = c.capacity_ah;
    r.capacity_sd_ah = c.capacity_sd_ah;
    const double nan = std::nan("");
    r.soh_est = ref_cap != nullptr ? c.capacity_ah / ref_cap->capacity_ah : nan;
    r.counted_ah = c.counted_ah;
    r.soh_counted = ref_cap != nullptr ? c.counted_ah / ref_cap->counted_ah : nan;
    r.counted_complete = c.counted_complete;
    if (std::isfinite(c.capacity_ah)) {
      const std::string source = c.capacity_estimated ? "estimator" : "counted";
      a.capacity_source = a.capacity_source.empty() || a.capacity_source == source ? source : "mixed";
    }
    r.r_growth_est_ohm = c.r_growth_ohm - ref->r_growth_ohm;
    r.r_step_growth_ohm = c.r_step_ohm - ref_step;
    r.r_discharge_step_growth_ohm = c.r_discharge_step_ohm - ref_dstep;
    r.r_discharge_onset_growth_ohm = c.r_discharge_onset_ohm - ref_onset;
    r.discharge_meas_ah = m.discharge_ah;
    r.soh_meas = ref_meas != nullptr ? m.discharge_ah / ref_meas->discharge_ah : nan;
    r.ir_meas_ohm = m.internal_resistance_ohm;
    r.ir_growth_meas_ohm = m.internal_resistance_ohm - ref_ir;
    r.learned = c.learned;
    a.rows.push_back(r);
  }
  score(a);
  return a;
}

nlohmann::json aging_json(const AgingComparison& a) {
  const auto fit = [](const LineFit& f) {
    return nlohmann::json{{"n", f.n}, {"pearson_r", num(f.pearson)}, {"slope", num(f.slope)},
                          {"intercept_ohm", num(f.intercept)}};
  };
  return {{"cycles_compared", a.rows.size()},
          {"cycles_scored", a.cycles_scored},
          {"soh_mean_abs_err_pp", num(a.soh_mae_pp)},
          {"soh_max_abs_err_pp", num(a.soh_max_abs_pp)},
          {"capacity_source", a.capacity_source},
          {"soh_counted_mean_abs_err_pp", num(a.soh_counted_mae_pp)},
          {"r_growth_vs_cycler_ir_growth", fit(a.film_vs_ir)},
          {"r_step_growth_vs_cycler_ir_growth", fit(a.step_vs_ir)},
          {"r_discharge_step_growth_vs_cycler_ir_growth", fit(a.discharge_step_vs_ir)},
          {"r_discharge_onset_growth_vs_cycler_ir_growth", fit(a.discharge_onset_vs_ir)},
          {"note",
           "soh: the charges' capacity_ah / its first (capacity_source: the estimator's open-circuit capacity, or the "
           "counted charge where it identifies none), against the cycler's discharge capacity / its first, same cycle; "
           "soh_counted: the counted charge's; resistance: the estimate's growth (y) regressed on the cycler's internal-resistance growth (x)"}};
}

std::string write_aging_outputs(const std::filesystem::path& dir, const AgingComparison& a) {
  CsvWriter w(dir / "aging.csv", {"cycle", "capacity_est_ah", "capacity_sd_ah", "soh_est", "discharge_meas_ah",
                                  "soh_meas", "r_growth_est_ohm", "r_step_growth_ohm", "ir_meas_ohm",
                                  "ir_growth_meas_ohm", "learned", "counted_ah", "soh_counted",
                                  "r_discharge_step_growth_ohm", "counted_complete", "r_discharge_onset_growth_ohm"});
  const auto cell = [&w](double v) {
    if (std::isfinite(v)) w.cell(v);
    else w.cell("");
  };
  for (const AgingRow& r : a.rows) {
    w.cell(r.cycle);
    for (double v : {r.capacity_est_ah, r.capacity_sd_ah, r.soh_est, r.discharge_meas_ah, r.soh_meas,
                     r.r_growth_est_ohm, r.r_step_growth_ohm, r.ir_meas_ohm, r.ir_growth_meas_ohm})
      cell(v);
    w.cell(r.learned ? 1 : 0);
    cell(r.counted_ah);
    cell(r.soh_counted);
    cell(r.r_discharge_step_growth_ohm);
    w.cell(r.counted_complete ? 1 : 0);
    cell(r.r_discharge_onset_growth_ohm);
    w.end_row();
  }
  w.commit();
  if (a.rows.empty()) return "no CC charge of the record in a cycle the cycler reported: no plots";
  // No capacity to compare (no whole charge by the cell's voltage limits): the resistance plot only.
  const bool any_soh =
      std::any_of(a.rows.begin(), a.rows.end(), [](const AgingRow& r) { return std::isfinite(r.soh_meas); });
  const std::string capacity_gp =
      "set output 'capacity.png.tmp'\nset title 'State of health: the estimate beside the cycler'\n"
      "set ylabel 'capacity / first capacity'\n"
      "plot 'aging.csv' using 1:6 skip 1 with points pt 7 ps 0.5 title 'cycler: discharge capacity', "
      "'' using 1:4 skip 1 with lines lw 2 title 'estimate: capacity_ah', "
      "'' using 1:13 skip 1 with lines lw 1 dt 2 title 'counted charge'\n";
  const std::string gp =
      "# Made by bmssim estimate; run in this folder: gnuplot plots.gp\n"
      "set datafile separator ','\nset datafile missing ''\nset terminal pngcairo size 1100,700 noenhanced\nset grid\n"
      "set key top right\nset xlabel 'cycle'\n" +
      (any_soh ? capacity_gp : std::string()) +
      "set output 'resistance.png.tmp'\nset title 'Resistance growth since the first compared charge'\n"
      "set ylabel 'growth (ohm)'\n"
      "plot 'aging.csv' using 1:10 skip 1 with points pt 7 ps 0.5 title 'cycler: internal resistance', "
      "'' using 1:7 skip 1 with lines lw 2 title 'estimate: r_growth_ohm (film)', "
      "'' using 1:8 skip 1 with points pt 6 ps 0.4 title 'measured: voltage step at the charge onset', "
      "'' using 1:14 skip 1 with points pt 2 ps 0.4 title 'measured: voltage step at the discharge onset', "
      "'' using 1:16 skip 1 with points pt 5 ps 0.4 title 'measured: discharge onset at the step instant'\n";
  AtomicFileWriter script(dir / "plots.gp");
  script.append(gp);
  script.commit();
  GnuplotOptions g;
  g.working_dir = dir;
  std::string problem;
  std::vector<std::string> plots{"resistance.png"};
  if (any_soh) plots.insert(plots.begin(), "capacity.png");
  commit_plots(dir, plots, run_gnuplot("plots.gp", g), problem);
  return problem.empty() ? problem : problem + ": no plots";
}

}  // namespace bms
