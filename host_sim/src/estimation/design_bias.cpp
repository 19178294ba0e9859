#include "estimation/design_bias.hpp"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <vector>

#include "estimation/estimate_run.hpp"
#include "io/input_error.hpp"
#include "sim/cycler.hpp"

namespace bms {
namespace {

constexpr int kCycles = 3;
constexpr int kMeshVolumes = 40;
constexpr double kRtol = 1e-9;
constexpr double kCvEndCRate = 0.1;  // C/10: at C/20 the NMC template's anode fills at the separator (flat OCP above x = 0.9)

EstimateData nominal_run(const CellParameters& cell) {
  SimulationConfig cfg;
  cfg.cell = cell;
  cfg.mesh = {kMeshVolumes, kMeshVolumes, kMeshVolumes, kMeshVolumes};
  cfg.solver.rtol = kRtol;
  cfg.temperature_k = cell.thermal.ambient_temperature_k;
  cfg.ic = default_initial_conditions(cell);
  CccvProtocol p;
  p.cycles = kCycles;
  p.current_a = cell.nominal_capacity_ah;  // 1C
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

}  // namespace

DesignBias design_time_bias(const CellParameters& nominal_in) {
  const auto wall0 = std::chrono::steady_clock::now();
  // The reduced model's own error against the plain DFN: the cell's effects (a contact
  // resistance, hysteresis, ...) are the model effects' to carry, not the bias's.
  CellParameters nominal = nominal_in;
  nominal.effects = CellEffectParameters{};
  const EstimateData d = nominal_run(nominal);
  EstimateOptions o;
  o.model = "reduced";
  o.profile = fw::Profile::best;
  o.overrides.learning = false;
  o.overrides.model_bias_ohm = 0.0;  // the bias itself is what the run measures
  o.ic = default_initial_conditions(nominal);
  const EstimateResult res = run_estimate(d, nominal, o);
  std::vector<double> ratios;
  double start = std::nan("");
  for (const EstimateRow& row : res.rows) {
    if (row.mode != fw::Mode::cc_charge) {
      start = std::nan("");
      continue;
    }
    if (std::isnan(start)) start = row.t_s;
    if (row.t_s - start > res.config.warmup_s && row.model_current_a < 0.0) ratios.push_back(row.z_v / -row.model_current_a);
  }
  if (ratios.empty())
    throw RuntimeFailure("design-time bias of cell '" + nominal.name +
                         "': no CC-charge tick after the warm-up in the nominal run");
  std::nth_element(ratios.begin(), ratios.begin() + static_cast<long>(ratios.size() / 2), ratios.end());
  DesignBias b;
  b.bias_ohm = ratios[ratios.size() / 2];
  b.ticks = ratios.size();
  b.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  return b;
}

}  // namespace bms
