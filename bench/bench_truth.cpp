// Speed of the truth model (issue 2): a 1-hour 1C discharge and 5 paper CCCV cycles.
#include <benchmark/benchmark.h>

#include <cmath>

#include "cell/paper_cell.hpp"
#include "sim/cell_catalog.hpp"
#include "sim/cycler.hpp"

namespace {

using namespace bms;

SimulationConfig config(const CellParameters& cell) {
  SimulationConfig cfg;
  cfg.cell = cell;
  cfg.temperature_k = cell.thermal.ambient_temperature_k;
  cfg.ic = default_initial_conditions(cell);
  return cfg;
}

// A constant-current discharge to 2.0 V; arguments: -log10(rtol) (6 = the simulator's
// default, 4 = PyBaMM's, 3 = PETLION's), then optionally finite volumes per region and per
// particle (default 20, 20; PETLION's benchmark mesh is 10, 10). Includes building the model
// and solver; the Jacobian pattern is cached per process, and the BPX file is read outside
// the loop.
void run_discharge(benchmark::State& state, const CellParameters& cell, double current_a) {
  auto cfg = config(cell);
  cfg.solver.rtol = std::pow(10.0, -static_cast<double>(state.range(0)));
  if (state.range(1) > 0) cfg.mesh.n_neg = cfg.mesh.n_sep = cfg.mesh.n_pos = static_cast<int>(state.range(1));
  if (state.range(2) > 0) cfg.mesh.n_r = static_cast<int>(state.range(2));
  const std::vector<double> t{0.0, 4000.0}, i{current_a, current_a};
  double sim_s = 0.0;
  SolverStats stats;
  for (auto _ : state) {
    const auto r = run_current_profile(cfg, t, i, 2.0, 4.0);
    sim_s = r.sim_s;
    stats = r.stats;
    benchmark::DoNotOptimize(r.samples.data());
  }
  state.counters["simulated_s"] = sim_s;
  state.counters["steps"] = static_cast<double>(stats.steps);
  state.counters["res_evals"] = static_cast<double>(stats.residual_evals);
  state.counters["jac_evals"] = static_cast<double>(stats.jacobian_evals);
  state.counters["colors"] = static_cast<double>(stats.colors);
}

// About:Energy cell, 2 A (1C) from full charge: about one hour.
void BM_OneHourDischarge1C_AboutEnergy(benchmark::State& state) {
  run_discharge(state, load_cell("aboutenergy"), 2.0);
}
BENCHMARK(BM_OneHourDischarge1C_AboutEnergy)
    ->Args({6, 0, 0})->Args({4, 0, 0})->Args({3, 10, 10})
    ->Unit(benchmark::kMillisecond)->MinTime(2.0);

// Paper cell, 2.3 A (its nominal 1C) from the paper's initial state.
void BM_Discharge1C_Paper(benchmark::State& state) { run_discharge(state, make_paper_cell(), 2.3); }
BENCHMARK(BM_Discharge1C_Paper)
    ->Args({6, 0, 0})->Args({4, 0, 0})->Args({3, 10, 10})
    ->Unit(benchmark::kMillisecond)->MinTime(2.0);

// Five CCCV cycles of the paper cell with every 0.2 s sample recorded (as `simulate` does).
void BM_PaperFiveCycles(benchmark::State& state) {
  const auto cfg = config(make_paper_cell());
  CccvProtocol p;
  p.cycles = 5;
  double sim_s = 0.0;
  for (auto _ : state) {
    const auto r = run_cccv(cfg, p);
    sim_s = r.sim_s;
    benchmark::DoNotOptimize(r.samples.data());
  }
  state.counters["simulated_s"] = sim_s;
}
BENCHMARK(BM_PaperFiveCycles)->Unit(benchmark::kSecond)->Iterations(2);

}  // namespace
