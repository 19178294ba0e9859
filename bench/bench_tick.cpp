// Host time per firmware tick (issue 3: "host time per tick (benchmark)"): BmsCore with the
// reduced model, double and float, in CC charge with RCSI learning, in CV (voltage-driven
// Newton), and the two rare worst cases: a state re-synchronisation and the catch-up after a
// gap of missed ticks. Target instruction counts are measured under QEMU
// (docs/results/target.md); this is the host view. Counters report the static footprint.
#include <benchmark/benchmark.h>

#include <vector>

#include "bms/fw/estimation/bms_core.hpp"
#include "bms/fw/config/make_config.hpp"
#include "bms/fw/model/paper_cell.hpp"

namespace {

using bms::fw::TickInput;

template <typename Scalar>
struct Plant {
  std::vector<TickInput<Scalar>> discharge, charge;
};

// A synthetic cell (the same reduced model, film 1 % above the estimator's start): 2000 s of
// 2.5 A discharge, then 800 s of 2.5 A charge.
template <typename Scalar>
const Plant<Scalar>& plant() {
  static const Plant<Scalar> p = [] {
    Plant<Scalar> out;
    bms::fw::ReducedCell<double> cell;
    cell.init_default();
    const double film = 1.01 * bms::fw::PaperCellTraits::kInitialFilmOhmM2;
    for (int k = 0; k < 10000; ++k) {
      const auto r = cell.step_current(2.5, film, 0.2);
      out.discharge.push_back({static_cast<Scalar>(r.voltage_v), Scalar(2.5), true});
    }
    for (int k = 0; k < 4000; ++k) {
      const auto r = cell.step_current(-2.5, film, 0.2);
      out.charge.push_back({static_cast<Scalar>(r.voltage_v), Scalar(-2.5), true});
    }
    return out;
  }();
  return p;
}

template <typename Scalar>
void add_footprint(benchmark::State& state) {
  using Core = bms::fw::BmsCore<Scalar, bms::fw::ReducedCell<Scalar>, 1, 0>;
  state.counters["core_bytes"] = static_cast<double>(sizeof(Core));
  state.counters["model_bytes"] = static_cast<double>(sizeof(bms::fw::ReducedCell<Scalar>));
  state.counters["nvm_image_bytes"] = static_cast<double>(sizeof(typename Core::State));
}

// One tick in CC charge with RCSI learning (the paper's settings: learning from the start).
template <typename Scalar>
void BM_TickCcChargeLearning(benchmark::State& state) {
  using Model = bms::fw::ReducedCell<Scalar>;
  using Core = bms::fw::BmsCore<Scalar, Model, 1, 0>;
  const auto& p = plant<Scalar>();
  Model model;
  model.init_default();
  Core core(bms::fw::paper_cell_config<Core>(bms::fw::Profile::paper), model);
  for (const auto& in : p.discharge) core.tick(in);
  for (std::size_t k = 0; k < 100; ++k) core.tick(p.charge[k]);
  const auto start = core.save();
  std::size_t k = 100;
  std::size_t learning = 0, ticks = 0;
  for (auto _ : state) {
    const auto out = core.tick(p.charge[k]);
    benchmark::DoNotOptimize(out.r_film_est_ohm_m2);
    learning += out.rcsi_active ? 1u : 0u;
    ++ticks;
    if (++k == p.charge.size()) {
      state.PauseTiming();
      core.restore(start);
      k = 100;
      state.ResumeTiming();
    }
  }
  state.counters["learning_share"] = static_cast<double>(learning) / static_cast<double>(ticks);
  add_footprint<Scalar>(state);
}
BENCHMARK_TEMPLATE(BM_TickCcChargeLearning, double);
BENCHMARK_TEMPLATE(BM_TickCcChargeLearning, float);

// One voltage-driven model step (CV: Newton on the current).
template <typename Scalar>
void BM_ModelStepVoltage(benchmark::State& state) {
  bms::fw::ReducedCell<Scalar> model;
  model.init_default();
  for (int k = 0; k < 5000; ++k) model.step_current(Scalar(-2.5), Scalar(bms::fw::paper::kInitialFilm_ohm_m2), Scalar(0.2));
  const auto start = model.state();
  int k = 0;
  for (auto _ : state) {
    const auto r = model.step_voltage(Scalar(3.6), Scalar(bms::fw::paper::kInitialFilm_ohm_m2), Scalar(0.2));
    benchmark::DoNotOptimize(r.current_a);
    if (++k == 500) {
      state.PauseTiming();
      model.restore(start);
      k = 0;
      state.ResumeTiming();
    }
  }
}
BENCHMARK_TEMPLATE(BM_ModelStepVoltage, double);
BENCHMARK_TEMPLATE(BM_ModelStepVoltage, float);

// The state re-synchronisation from a model 1 % off (once per CV phase; up to 42 model
// evaluations).
template <typename Scalar>
void BM_Resync(benchmark::State& state) {
  bms::fw::ReducedCell<Scalar> truth, model;
  truth.init_default();
  model.init(Scalar(0.8408 * 1.01), Scalar(0.1592 * 1.01), Scalar(1266.9 * 1.01));
  for (int k = 0; k < 3000; ++k) {
    truth.step_current(Scalar(2.5), Scalar(bms::fw::paper::kInitialFilm_ohm_m2), Scalar(0.2));
    model.step_current(Scalar(2.5), Scalar(bms::fw::paper::kInitialFilm_ohm_m2), Scalar(0.2));
  }
  const Scalar v = truth.peek_voltage(Scalar(0.2), Scalar(bms::fw::paper::kInitialFilm_ohm_m2), Scalar(0.2));
  const Scalar inventory = bms::fw::ReducedCell<Scalar>::inventory_of(Scalar(0.8408), Scalar(0.1592));
  const auto start = model.state();
  bool ok = true;
  for (auto _ : state) {
    ok = ok && model.resync(v, Scalar(0.2), Scalar(bms::fw::paper::kInitialFilm_ohm_m2), Scalar(0.2), inventory);
    state.PauseTiming();
    model.restore(start);
    state.ResumeTiming();
  }
  if (!ok) state.SkipWithError("resync failed");
}
BENCHMARK_TEMPLATE(BM_Resync, double);
BENCHMARK_TEMPLATE(BM_Resync, float);

// The tick in which samples return after a gap of state.range(0) missed ticks (catch-up).
void BM_TickAfterGap(benchmark::State& state) {
  using Model = bms::fw::ReducedCell<double>;
  using Core = bms::fw::BmsCore<double, Model, 1, 0>;
  const auto& p = plant<double>();
  Model model;
  model.init_default();
  Core core(bms::fw::paper_cell_config<Core>(bms::fw::Profile::paper), model);
  for (std::size_t k = 0; k < 2000; ++k) core.tick(p.discharge[k]);
  const auto start = core.save();
  const auto gap = static_cast<std::size_t>(state.range(0));
  for (auto _ : state) {
    state.PauseTiming();
    core.restore(start);
    for (std::size_t k = 0; k < gap; ++k) core.tick(TickInput<double>{0.0, 0.0, false});
    state.ResumeTiming();
    const auto out = core.tick(p.discharge[2000 + gap]);
    benchmark::DoNotOptimize(out.z_v);
  }
}
BENCHMARK(BM_TickAfterGap)->Arg(10)->Arg(600);

}  // namespace
