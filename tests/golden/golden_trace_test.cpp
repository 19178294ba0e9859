// Golden per-tick trace of the estimator (PX4 replay style): the recorded CCCV cycle of
// target/data/ through BmsCore<double> with each profile and the film path it names. Every
// tick's outputs are hashed bit for bit in blocks of kBlockTicks; the committed trace
// (tests/golden/*.trace) holds each block's hash and its last tick's values, so any change to
// any output of any tick fails here and the first block that differs says where and by how
// much. A change made on purpose is recorded with
//   scripts/regenerate-golden.sh
// and the diff of the trace files goes into review.
#include <gtest/gtest.h>

#include <algorithm>
#include <cinttypes>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>
#include <vector>

#include "bms/fw/estimation/bms_core.hpp"
#include "bms/fw/config/make_config.hpp"
#include "bms/fw/model/reduced_cell.hpp"
#include "replay_data.hpp"

namespace bms {
namespace {

using Output = fw::TickOutput<double, 1>;
constexpr std::size_t kBlockTicks = 500;

// FNV-1a over the bytes of every output field (doubles by their bit patterns).
class TraceHash {
 public:
  void add(const void* p, std::size_t n) {
    const auto* b = static_cast<const unsigned char*>(p);
    for (std::size_t i = 0; i < n; ++i) h_ = (h_ ^ b[i]) * 1099511628211ull;
  }
  void add(const Output& o) {
    const auto mode = static_cast<std::uint32_t>(o.mode);
    const std::uint32_t active = o.rcsi_active ? 1u : 0u;
    add(&mode, sizeof mode);
    add(&active, sizeof active);
    for (double v : {o.r_film_est_ohm_m2, o.z_v, o.model_voltage_v, o.model_current_a, o.j_side_a_m3, o.li_loss_ah,
                     o.theta[0], o.theta[1], o.film_initial_ohm_m2, o.growth_gain, o.inventory_deviation,
                     o.markov_v_per_ohm_m2, o.inventory_sensitivity_v, o.growth_ohm_m2})
      add(&v, sizeof v);
    add(&o.status, sizeof o.status);
    add(&o.tick, sizeof o.tick);
    add(&o.newton_iterations, sizeof o.newton_iterations);
  }
  std::uint64_t value() const { return h_; }

 private:
  std::uint64_t h_ = 14695981039346656037ull;
};

template <class Core>
std::vector<std::string> trace_with(fw::Profile profile) {
  fw::ReducedCell<double> model;
  model.init_default();
  Core core(fw::paper_cell_config<Core>(profile), model);
  std::vector<std::string> lines;
  lines.push_back("# block_end_tick,hash,mode,r_film_est_ohm_m2,z_v,model_voltage_v,growth_gain,inventory_deviation,status");
  TraceHash hash;
  for (std::size_t k = 0; k < kReplayTicks; ++k) {
    const Output o = core.tick({bms_replay_voltage_10uv[k] * 1e-5, bms_replay_current_100ua[k] * 1e-4, true});
    hash.add(o);
    if ((k + 1) % kBlockTicks == 0 || k + 1 == kReplayTicks) {
      char line[320];
      std::snprintf(line, sizeof line, "%zu,%016" PRIx64 ",%s,%.17g,%.17g,%.17g,%.17g,%.17g,%u", k + 1, hash.value(),
                    fw::mode_name(o.mode), o.r_film_est_ohm_m2, o.z_v, o.model_voltage_v, o.growth_gain,
                    o.inventory_deviation, static_cast<unsigned>(o.status));
      lines.emplace_back(line);
    }
  }
  return lines;
}

// The core the profile names, chosen at start as bms-firmware and bmssim estimate choose it.
std::vector<std::string> trace_of(fw::Profile profile) {
  return fw::with_core_for<double, fw::ReducedCell<double>, 1, 0>(
      profile, [&](auto tag) { return trace_with<typename decltype(tag)::type>(profile); });
}

std::string golden_path(const char* name) { return std::string(BMS_SOURCE_DIR) + "/tests/golden/" + name; }

void check_against_golden(fw::Profile profile, const char* name) {
  const char* tunables = std::getenv("GLIBC_TUNABLES");
  ASSERT_TRUE(tunables != nullptr && std::strstr(tunables, "-FMA") != nullptr)
      << "run through ctest or scripts/regenerate-golden.sh: the trace is made with glibc's generic exp/log "
         "(GLIBC_TUNABLES=glibc.cpu.hwcaps=-AVX2,-FMA), the same on every x86-64 machine";
  const std::vector<std::string> now = trace_of(profile);
  const std::string path = golden_path(name);
  if (std::getenv("BMS_GOLDEN_REGENERATE") != nullptr) {
    std::ofstream out(path);
    for (const auto& l : now) out << l << '\n';
    ASSERT_TRUE(out.good()) << "cannot write " << path;
    std::printf("regenerated %s (%zu lines)\n", path.c_str(), now.size());
    return;
  }
  std::ifstream in(path);
  ASSERT_TRUE(in.good()) << path << ": missing; run scripts/regenerate-golden.sh";
  std::vector<std::string> golden;
  for (std::string l; std::getline(in, l);) golden.push_back(l);
  ASSERT_EQ(golden.size(), now.size()) << path << ": block count differs";
  for (std::size_t i = 0; i < now.size(); ++i)
    ASSERT_EQ(golden[i], now[i]) << path << ": first difference in block " << i
                                 << " (golden above, now below); if the change is meant, run "
                                    "scripts/regenerate-golden.sh and review the diff";
}

TEST(GoldenTrace, BestProfileEveryTickBitForBit) { check_against_golden(fw::Profile::best, "best_profile.trace"); }
TEST(GoldenTrace, PaperProfileEveryTickBitForBit) { check_against_golden(fw::Profile::paper, "paper_profile.trace"); }

// The largest relative distance of the reported film from the cycle's final estimate over the
// learning ticks, with the identifier's outputs held until it settles (the default) or not.
double largest_swing_while_learning(bool hold) {
  return fw::with_core_for<double, fw::ReducedCell<double>, 1, 0>(fw::Profile::best, [&](auto tag) {
    using Core = typename decltype(tag)::type;
    fw::ReducedCell<double> model;
    model.init_default();
    auto cfg = fw::paper_cell_config<Core>(fw::Profile::best);
    if constexpr (Core::FilmPath::kKind == fw::FilmPathKind::identifier) cfg.film_path.hold_until_settled = hold;
    Core core(cfg, model);
    std::vector<double> film;
    for (std::size_t k = 0; k < kReplayTicks; ++k) {
      const Output o = core.tick({bms_replay_voltage_10uv[k] * 1e-5, bms_replay_current_100ua[k] * 1e-4, true});
      if (o.rcsi_active) film.push_back(o.r_film_est_ohm_m2);
    }
    double worst = 0.0;
    for (double f : film) worst = std::max(worst, std::fabs(f / film.back() - 1.0));
    return film.empty() ? -1.0 : worst;
  });
}

// The first seconds of a (re)started fit swing the film along the film-growth-inventory
// direction its prior leaves open; the outputs hold the prior until the fit has settled.
TEST(GoldenTrace, BestProfileHoldsThePriorUntilTheFitSettles) {
  const double held = largest_swing_while_learning(true), free = largest_swing_while_learning(false);
  std::printf("largest swing over the learning ticks: held %.4f, not held %.4f\n", held, free);
  EXPECT_GE(held, 0.0);
  EXPECT_LT(held, 0.03);
  EXPECT_GT(free, 3.0 * held);
}

TEST(GoldenTrace, TheHashSeesALastBitChange) {
  Output a{};
  a.r_film_est_ohm_m2 = 0.0034;
  Output b = a;
  b.r_film_est_ohm_m2 = std::nextafter(a.r_film_est_ohm_m2, 1.0);
  TraceHash ha, hb;
  ha.add(a);
  hb.add(b);
  EXPECT_NE(ha.value(), hb.value());
}

}  // namespace
}  // namespace bms
