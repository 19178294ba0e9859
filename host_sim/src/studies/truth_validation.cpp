#include "studies/truth_validation.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>

#include "bms/fw/model/paper_cell.hpp"
#include "cell/paper_cell.hpp"
#include "io/measured_profile.hpp"
#include "sim/cell_catalog.hpp"
#include "io/statistics.hpp"

namespace bms {
namespace {

SimulationConfig config_for(const CellParameters& cell, const DfnMesh& mesh) {
  SimulationConfig cfg;
  cfg.cell = cell;
  cfg.mesh = mesh;
  cfg.temperature_k = cell.thermal.ambient_temperature_k;
  cfg.ic = default_initial_conditions(cell);
  return cfg;
}

CccvProtocol protocol_for(const CellParameters& cell, int cycles, double current_a) {
  CccvProtocol p;
  p.cycles = cycles;
  p.current_a = current_a;
  p.v_min = cell.lower_voltage_v;
  p.v_max = cell.upper_voltage_v;
  return p;
}


// Voltages of one mode of one cycle, indexed by samples since the mode began.
std::vector<double> phase_voltages(const SimulationResult& r, int cycle, Mode mode) {
  std::vector<double> v;
  for (const auto& s : r.samples)
    if (s.cycle == cycle && s.mode == mode) v.push_back(s.voltage_v);
  return v;
}

double median_abs_diff_mv(const std::vector<double>& a, const std::vector<double>& b) {
  std::vector<double> d;
  for (size_t i = 0; i < std::min(a.size(), b.size()); ++i) d.push_back(1e3 * std::abs(a[i] - b[i]));
  return d.empty() ? 0.0 : stats::median(d);  // no common samples: no difference
}

}  // namespace

ConservationReport check_conservation(const CellParameters& cell, int cycles) {
  ConservationReport rep;
  const double capacity_mol = cell.positive.solid_fraction * cell.positive.thickness_m * cell.electrode_area_m2 *
                              cell.positive.max_concentration_mol_m3;
  {
    CellParameters off = cell;
    off.side.enabled = false;
    const auto r = run_cccv(config_for(off, DfnMesh{}), protocol_for(off, cycles, fw::paper::kCurrent_a));
    for (int c = 1; c <= cycles; ++c) {
      const SampleRecord* first = nullptr;
      const SampleRecord* last = nullptr;
      for (const auto& s : r.samples)
        if (s.cycle == c) {
          if (!first) first = &s;
          last = &s;
        }
      rep.inventory_drift_rel_per_cycle =
          std::max(rep.inventory_drift_rel_per_cycle, std::abs(last->inventory_mol - first->inventory_mol) / first->inventory_mol);
    }
    const double cap_neg = cell.negative.solid_fraction * cell.negative.thickness_m * cell.electrode_area_m2 *
                           cell.negative.max_concentration_mol_m3;
    const double solid0 = cap_neg * r.samples.front().stoich_neg + capacity_mol * r.samples.front().stoich_pos;
    for (const auto& s : r.samples) {
      rep.max_stoich_sum_error = std::max(rep.max_stoich_sum_error, std::abs(s.stoich_neg + s.stoich_pos - 1.0));
      rep.max_solid_lithium_drift_rel =
          std::max(rep.max_solid_lithium_drift_rel,
                   std::abs(cap_neg * s.stoich_neg + capacity_mol * s.stoich_pos - solid0) / solid0);
    }
    const auto& s0 = r.samples.front();
    const auto& s1 = r.samples.back();
    const double dn_cathode = (s1.stoich_pos - s0.stoich_pos) * capacity_mol;
    rep.throughput_vs_cathode_rel = std::abs(s1.charge_ah * 3600.0 / kFaradayC_mol - dn_cathode) / capacity_mol;
  }
  {
    const auto r = run_cccv(config_for(cell, DfnMesh{}), protocol_for(cell, cycles, fw::paper::kCurrent_a));
    rep.li_loss_mol = r.samples.front().inventory_mol - r.samples.back().inventory_mol;
    const double per_a_m3 = cell.electrode_area_m2 * cell.negative.thickness_m / kFaradayC_mol;
    double integral = 0.0, charge_trap = 0.0, charge_state = 0.0;
    for (size_t i = 1; i < r.samples.size(); ++i) {
      const auto& a = r.samples[i - 1];
      const auto& b = r.samples[i];
      const double dt = b.t_s - a.t_s;
      integral += -0.5 * (a.j_s_a_m3 + b.j_s_a_m3) * dt * per_a_m3;
      // The integrator's charge state against the trapezoid of the samples, on intervals
      // without a mode switch (the current jumps at a switch, between two samples).
      if (a.mode == b.mode) {
        charge_trap += 0.5 * (a.current_a + b.current_a) * dt / 3600.0;
        charge_state += b.charge_ah - a.charge_ah;
      }
    }
    rep.li_side_current_mol = integral;
    rep.li_loss_rel_error = std::abs(rep.li_loss_mol - integral) / std::abs(integral);
    const double throughput_ah = capacity_mol * kFaradayC_mol / 3600.0;
    rep.charge_state_vs_trapezoid_rel = std::abs(charge_state - charge_trap) / throughput_ah;
  }
  return rep;
}

std::vector<ConvergenceRow> check_mesh_convergence(const CellParameters& cell, const std::vector<int>& points) {
  std::vector<ConvergenceRow> rows;
  for (int p : points) {
    ConvergenceRow row;
    row.points = p;
    row.radial = p;
    const auto t0 = std::chrono::steady_clock::now();
    const DfnMesh base{p, p, p, p}, fine{2 * p, 2 * p, 2 * p, 2 * p};
    const auto a = run_cccv(config_for(cell, base), protocol_for(cell, 1, fw::paper::kCurrent_a));
    row.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    const auto b = run_cccv(config_for(cell, fine), protocol_for(cell, 1, fw::paper::kCurrent_a));
    row.unknowns = DfnModel(cell, base, 298.15).size();
    double sum2 = 0.0, sum2_in = 0.0;
    size_t count = 0, count_in = 0;
    for (const auto& pa : a.phases) {
      if (pa.mode != Mode::cc_charge && pa.mode != Mode::cc_discharge) continue;
      const PhaseMark* pb = nullptr;
      for (const auto& q : b.phases)
        if (q.cycle == pa.cycle && q.mode == pa.mode) pb = &q;
      if (!pb) continue;
      row.max_phase_end_shift_s = std::max(row.max_phase_end_shift_s,
                                           std::abs((pa.t_end_s - pa.t_start_s) - (pb->t_end_s - pb->t_start_s)));
      const double common = std::min(pa.t_end_s - pa.t_start_s, pb->t_end_s - pb->t_start_s);
      // B's voltage at the same time since its phase began, linear between its samples.
      size_t j = 0;
      for (const auto& sa : a.samples) {
        if (sa.cycle != pa.cycle || sa.mode != pa.mode) continue;
        const double tau = sa.t_s - pa.t_start_s;
        if (tau > common) break;
        const double tb = pb->t_start_s + tau;
        while (j + 1 < b.samples.size() && b.samples[j + 1].t_s < tb) ++j;
        if (j + 1 >= b.samples.size()) break;
        const auto& b0 = b.samples[j];
        const auto& b1 = b.samples[j + 1];
        if (b0.mode != pa.mode || b1.mode != pa.mode || b0.t_s > tb) continue;
        const double w = (tb - b0.t_s) / (b1.t_s - b0.t_s);
        const double d = 1e3 * std::abs(sa.voltage_v - (b0.voltage_v + w * (b1.voltage_v - b0.voltage_v)));
        row.max_diff_mv = std::max(row.max_diff_mv, d);
        sum2 += d * d;
        ++count;
        if (tau > 30.0 && tau < common - 30.0) {
          row.interior_max_diff_mv = std::max(row.interior_max_diff_mv, d);
          sum2_in += d * d;
          ++count_in;
        }
      }
    }
    row.rms_diff_mv = count ? std::sqrt(sum2 / static_cast<double>(count)) : 0.0;
    row.interior_rms_diff_mv = count_in ? std::sqrt(sum2_in / static_cast<double>(count_in)) : 0.0;
    rows.push_back(row);
  }
  return rows;
}

PaperObservables paper_observables(int cycles) {
  PaperObservables o;
  const CellParameters cell = make_paper_cell();
  const auto r = run_cccv(config_for(cell, DfnMesh{}), protocol_for(cell, cycles, fw::paper::kCurrent_a));
  double total = 0.0, cc = 0.0, cv = 0.0, dis = 0.0;
  for (const auto& c : r.cycles) {
    o.growth_pct_per_cycle.push_back(c.growth_pct);
    cc += c.growth_by_mode_ohm_m2[static_cast<int>(Mode::cc_charge)];
    cv += c.growth_by_mode_ohm_m2[static_cast<int>(Mode::cv_charge)];
    dis += c.growth_by_mode_ohm_m2[static_cast<int>(Mode::cc_discharge)] +
           c.growth_by_mode_ohm_m2[static_cast<int>(Mode::cv_discharge)];
  }
  total = cc + cv + dis;
  o.growth_share_cc_charge = cc / total;
  o.growth_share_cv_charge = cv / total;
  o.growth_share_discharge = dis / total;
  for (int c = 1; c < cycles; ++c)
    o.dv_successive_cc_charge_mv.push_back(
        median_abs_diff_mv(phase_voltages(r, c, Mode::cc_charge), phase_voltages(r, c + 1, Mode::cc_charge)));
  const auto r2 = run_cccv(config_for(cell, DfnMesh{}), protocol_for(cell, 1, 2.495));
  const auto va = phase_voltages(r, 1, Mode::cc_charge), vb = phase_voltages(r2, 1, Mode::cc_charge);
  o.dv_current_2p495_mv = median_abs_diff_mv(va, vb);
  o.dv_current_2p495_start_mv = median_abs_diff_mv(std::vector<double>(va.begin(), va.begin() + 300),
                                                   std::vector<double>(vb.begin(), vb.begin() + 300));
  // Film subsystem, discretised exactly for a held J_s: R(k+1) = R(k) - T factor / a_n * J_s(k).
  DfnModel m(cell, DfnMesh{}, 298.15);
  const double pore_area_m2 = cell.negative.surface_area_per_volume_m() * cell.negative.thickness_m * cell.electrode_area_m2;
  o.film_drop_growth_mv = 1e3 * (r.cycles[0].r_film_end_ohm_m2 - r.cycles[0].r_film_start_ohm_m2) *
                          fw::paper::kCurrent_a / pore_area_m2;
  o.theta_m1 = 1.0;
  o.theta_n1 = -0.2 * m.film_growth_factor() / cell.negative.surface_area_per_volume_m();
  return o;
}

double rmse_against(const SimulationResult& r, const std::vector<double>& t_s, const std::vector<double>& v) {
  double sum2 = 0.0;
  size_t n = 0, j = 0;
  for (const auto& s : r.samples) {
    while (j < t_s.size() && t_s[j] < s.t_s - 1e-9) ++j;
    if (j >= t_s.size()) break;
    if (std::abs(t_s[j] - s.t_s) > 1e-9) continue;
    const double d = s.voltage_v - v[j];
    sum2 += d * d;
    ++n;
  }
  return n ? 1e3 * std::sqrt(sum2 / static_cast<double>(n)) : 0.0;
}

std::vector<MeasuredCase> compare_aboutenergy(const DfnMesh& mesh) {
  // PyBaMM's reference model of this BPX set has no SEI: the comparison runs without the side
  // reaction (and so without a film), as PyBaMM does.
  CellParameters cell = load_cell("aboutenergy");
  cell.side.enabled = false;
  // PyBaMM's published RMSE for the same BPX set (the About:Energy repository's notebook).
  std::vector<MeasuredCase> cases{{"C/20", "LFP_25degC_Co20.csv", 6.511, 0, 0, 0, 0, ""},
                                  {"1C", "LFP_25degC_1C.csv", 132.986, 0, 0, 0, 0, ""},
                                  {"2C", "LFP_25degC_2C.csv", 94.942, 0, 0, 0, 0, ""}};
  for (auto& c : cases) {
    const auto file = shared_dir() / "data/aboutenergy-lfp18650" / c.file;
    const auto prof = read_measured_profile(file, ProfileColumns::truth);
    const auto r = run_current_profile(config_for(cell, mesh), prof.t_s, prof.current_a,
                                       cell.lower_voltage_v - 0.5, cell.upper_voltage_v + 0.5);
    c.rmse_mv = rmse_against(r, prof.t_s, prof.voltage_v);
    double mx = 0.0;
    size_t j = 0;
    for (const auto& s : r.samples) {
      while (j < prof.t_s.size() && prof.t_s[j] < s.t_s - 1e-9) ++j;
      if (j < prof.t_s.size()) mx = std::max(mx, std::abs(s.voltage_v - prof.voltage_v[j]));
    }
    c.max_abs_mv = 1e3 * mx;
    c.samples = r.samples.size();
    c.wall_s = r.wall_s;
    c.note = r.note;
  }
  return cases;
}

}  // namespace bms
