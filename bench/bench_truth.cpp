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

// About:Energy cell, 2 A (1C) from full charge to 2.0 V: about one hour. Includes building the
// model and its Jacobian pattern (done once per run), excludes reading the BPX file.
// Argument: -log10(rtol), 6 = the simulator's default, 4 = PyBaMM's default.
void BM_OneHourDischarge1C_AboutEnergy(benchmark::State& state) {
  auto cfg = config(load_cell("aboutenergy"));
  cfg.solver.rtol = std::pow(10.0, -static_cast<double>(state.range(0)));
  const std::vector<double> t{0.0, 4000.0}, i{2.0, 2.0};
  double sim_s = 0.0;
  for (auto _ : state) {
    const auto r = run_current_profile(cfg, t, i, 2.0, 4.0);
    sim_s = r.sim_s;
    benchmark::DoNotOptimize(r.samples.data());
  }
  state.counters["simulated_s"] = sim_s;
}
BENCHMARK(BM_OneHourDischarge1C_AboutEnergy)->Arg(6)->Arg(4)->Unit(benchmark::kMillisecond)->MinTime(2.0);

// Paper cell, 2.3 A (its nominal 1C) CC discharge from the paper's initial state to 2.0 V.
void BM_Discharge1C_Paper(benchmark::State& state) {
  auto cfg = config(make_paper_cell());
  cfg.solver.rtol = std::pow(10.0, -static_cast<double>(state.range(0)));
  const std::vector<double> t{0.0, 4000.0}, i{2.3, 2.3};
  double sim_s = 0.0;
  for (auto _ : state) {
    const auto r = run_current_profile(cfg, t, i, 2.0, 4.0);
    sim_s = r.sim_s;
    benchmark::DoNotOptimize(r.samples.data());
  }
  state.counters["simulated_s"] = sim_s;
}
BENCHMARK(BM_Discharge1C_Paper)->Arg(6)->Arg(4)->Unit(benchmark::kMillisecond)->MinTime(2.0);

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
