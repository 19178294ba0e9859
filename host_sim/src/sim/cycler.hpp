#pragma once
// Runs the truth model through a cycling protocol (CCCV cycles, or a measured current
// profile) and samples it on a fixed output grid.
#include <functional>
#include <string>
#include <vector>

#include "bms/fw/estimation/operating_mode.hpp"
#include "cell/cell_parameters.hpp"
#include "dfn/dfn_solver.hpp"

namespace bms {

using Mode = fw::Mode;  // one numbering with the firmware and the CAN protocol
using fw::mode_name;
bool parse_mode(const std::string& s, Mode& out);

struct CccvProtocol {
  int cycles = 5;
  double current_a = 2.5;           // magnitude for CC charge and discharge
  double v_min = 2.0, v_max = 3.6;  // from the cell by default
  double cv_end_current_a = 0.125;  // CV ends when |I| falls below this
  double max_mode_s = 6.0 * 3600.0; // safety net per mode
};

struct InitialConditions {
  double stoich_neg = 0.8408, stoich_pos = 0.1592, electrolyte_mol_m3 = 1266.9;
  double r_film_ohm_m2 = 0.0;
};

struct SimulationConfig {
  CellParameters cell;
  DfnMesh mesh;
  SolverSettings solver;
  double dt_s = 0.2;
  double temperature_k = 298.15;  // isothermal cell temperature; with the thermal effect, ambient and initial
  InitialConditions ic;
  ModelEffects effects;
};

struct SampleRecord {
  double t_s;
  int cycle;
  Mode mode;
  double current_a, voltage_v, r_film_ohm_m2, j_s_a_m3, li_loss_ah, temperature_k;
  double charge_ah;     // integral of current (discharge positive)
  double inventory_mol; // lithium in solid + electrolyte
  double stoich_neg, stoich_pos;  // electrode-average stoichiometries
  double hysteresis_v;  // hysteresis state h (0 without the effect)
  double heat_w;        // heat generated (thermal effect only, else 0)
  double capacity_ah;   // open-circuit capacity of the solid inventory (bms/fw/model/open_circuit_capacity.hpp)
};

struct CycleSummary {
  int cycle;
  double r_film_start_ohm_m2, r_film_end_ohm_m2, growth_pct, li_loss_ah;
  double growth_by_mode_ohm_m2[5];  // film growth in each mode during this cycle
  double duration_by_mode_s[5];
};

struct PhaseMark {
  int cycle;
  Mode mode;
  double t_start_s, t_end_s;  // exact switching times (root-found), not grid times
};

struct SimulationResult {
  std::vector<SampleRecord> samples;
  std::vector<PhaseMark> phases;
  std::vector<CycleSummary> cycles;
  double sim_s = 0.0, wall_s = 0.0;
  SolverStats stats;
  std::string note;  // e.g. why a driven run ended early
};

using ProgressFn = std::function<void(double t_s, int cycle, Mode mode)>;

// Receives a run's output as it is produced, so a run of any length holds one sample at a
// time. A cycle's summary arrives when the cycle ends; a failure after it keeps it.
class SampleSink {
 public:
  virtual ~SampleSink() = default;
  virtual void on_sample(const SampleRecord& s) = 0;
  virtual void on_cycle(const CycleSummary& c) { (void)c; }
};

// Keeps every sample in memory (callers that need the whole run: studies, hil, tests).
class SampleCollector : public SampleSink {
 public:
  explicit SampleCollector(std::vector<SampleRecord>& to) : to_(to) {}
  void on_sample(const SampleRecord& s) override { to_.push_back(s); }

 private:
  std::vector<SampleRecord>& to_;
};

struct Experiment;

InitialConditions default_initial_conditions(const CellParameters& cell);
// The cell's initial state with the paper's initial-condition error: both stoichiometries and
// the electrolyte concentration scaled by (1 + pct/100). Throws InputError outside +-50 %.
InitialConditions perturbed_initial_conditions(const CellParameters& cell, double ic_error_pct);

// Throws RuntimeFailure naming the cycle, the phase and the time if the solver fails, and, if
// a particle's surface reaches its stoichiometry limit (within 1e-4) before the phase's own end
// (voltage limit or CV end current), which electrode's surface reached which limit.
SimulationResult run_cccv(const SimulationConfig& cfg, const CccvProtocol& protocol,
                          const ProgressFn& progress = {});

// Runs an experiment's steps `cycles` times (sim/experiment.hpp), sampling every cfg.dt_s into
// `sink`; the returned result holds no samples. Failures as run_cccv; a step whose end is
// already met when it starts ends at once.
SimulationResult run_experiment(const SimulationConfig& cfg, const Experiment& experiment, SampleSink& sink,
                                const ProgressFn& progress = {});

// Drives the model with current(t) (piecewise linear between samples; steps larger than
// step_threshold_a restart the integrator) and samples at the profile's times. Stops early,
// with a note, if the voltage leaves [v_stop_low, v_stop_high] or a particle empties.
SimulationResult run_current_profile(const SimulationConfig& cfg, const std::vector<double>& t_s,
                                     const std::vector<double>& current_a, double v_stop_low,
                                     double v_stop_high, const ProgressFn& progress = {});

}  // namespace bms
