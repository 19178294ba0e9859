// Target test application: replays a recorded CCCV cycle (replay_data.cpp, generated from
// target/data at build time) through the firmware's tick and prints the estimates, one line
// per tick. The same source runs on the host (the reference) and on the Cortex-M boards
// under QEMU; target/tools/compare_replay.py compares the two.
//
// Output: a "# columns ..." line, one line per tick, then "# name value" summary lines.
// Numbers are printed with %.17g (double) or %.9g (float): enough to read back every bit.
// The last column, instructions, is the tick's cost on the board (0 on the host).
#include <cmath>
#include <cstdint>
#include <cstdio>

#include "fw_source_hash.hpp"
#include "platform.hpp"
#include "replay_data.hpp"
#include "replay_tick.hpp"

namespace {

using bms::target::Scalar;

void put(Scalar v) {
  if (sizeof(Scalar) == sizeof(double)) {
    std::printf(" %.17g", static_cast<double>(v));
  } else {
    std::printf(" %.9g", static_cast<double>(v));
  }
}

// A "# name k1 k2 ..." summary line.
void put_ticks(const char* name, const std::size_t* ticks, std::size_t n) {
  std::printf("# %s", name);
  for (std::size_t i = 0; i < n; ++i) std::printf(" %u", static_cast<unsigned>(ticks[i]));
  std::printf("\n");
}

}  // namespace

int main() {
  bms::target::platform_start();
  // Static storage: the firmware's state is part of the image's RAM, not of the stack.
  static bms::target::ReplayFirmware fw;

  // Cost of reading the counter twice, reported so it can be subtracted.
  const std::uint64_t c0 = bms::target::platform_instructions();
  const std::uint64_t c1 = bms::target::platform_instructions();

  std::printf("# columns tick mode rcsi_active r_film_est_ohm_m2 z_v model_voltage_v model_current_a "
              "j_side_a_m3 li_loss_ah theta_1 theta_2 status newton_iterations instructions\n");
  std::uint32_t status_or = 0u;
  std::uint32_t newton_max = 0u;
  std::uint32_t cap_hits = 0u;
  bool finite = true;
  // The ticks that re-synchronised the model (their cost already holds one re-synchronisation,
  // so replay_check's bound adds its probe to the other ticks only).
  constexpr std::size_t kMaxResyncTicks = 32u;
  static std::size_t resync_ticks[kMaxResyncTicks];
  std::size_t resyncs_seen = 0u;
  for (std::size_t k = 0; k < kReplayTicks; ++k) {
    const std::uint32_t resyncs_before = fw.core.resync_count();
    const Scalar voltage_v = static_cast<Scalar>(static_cast<double>(bms_replay_voltage_10uv[k]) * 1e-5);
    const Scalar current_a = static_cast<Scalar>(static_cast<double>(bms_replay_current_100ua[k]) * 1e-4);
    const std::uint64_t t0 = bms::target::platform_instructions();
    const bms::target::TickOutput out = bms::target::replay_tick(fw, voltage_v, current_a);
    const std::uint64_t t1 = bms::target::platform_instructions();
    if (fw.core.resync_count() != resyncs_before && resyncs_seen < kMaxResyncTicks) resync_ticks[resyncs_seen++] = k;
    std::printf("%u %u %u", static_cast<unsigned>(k), static_cast<unsigned>(out.mode), out.rcsi_active ? 1u : 0u);
    put(out.r_film_est_ohm_m2);
    put(out.z_v);
    put(out.model_voltage_v);
    put(out.model_current_a);
    put(out.j_side_a_m3);
    put(out.li_loss_ah);
    put(out.theta[0]);
    put(out.theta[1]);
    std::printf(" %u %u %lu\n", static_cast<unsigned>(out.status), static_cast<unsigned>(out.newton_iterations),
                static_cast<unsigned long>(t1 - t0));
    status_or |= out.status;
    if (out.newton_iterations > newton_max) newton_max = out.newton_iterations;
    if (bms::fw::has_status(out.status, bms::fw::FwStatus::kModelNotConverged)) ++cap_hits;
    finite = finite && std::isfinite(out.r_film_est_ohm_m2) && std::isfinite(out.theta[0]) &&
             std::isfinite(out.theta[1]);
  }
  // Bounded worst case: the CV model step at its Newton cap (see replay_tick.hpp).
  const std::uint64_t p0 = bms::target::platform_instructions();
  const bms::fw::ModelTickResult<Scalar> probe = bms::target::newton_cap_probe(fw);
  const std::uint64_t p1 = bms::target::platform_instructions();
  std::printf("# newton_cap_probe iterations %u converged %u instructions %lu\n",
              static_cast<unsigned>(probe.newton_iterations), probe.converged ? 1u : 0u,
              static_cast<unsigned long>(p1 - p0));
  // The beyond-paper paths the paper-settings replay does not take: a state
  // re-synchronisation, and the tick after a 2-minute gap (last: it changes the firmware).
  const std::uint64_t r0 = bms::target::platform_instructions();
  const bool resync_ok = bms::target::resync_probe(fw);
  const std::uint64_t r1 = bms::target::platform_instructions();
  std::printf("# resync_probe converged %u instructions %lu\n", resync_ok ? 1u : 0u,
              static_cast<unsigned long>(r1 - r0));
  const std::size_t last = kReplayTicks - 1u;
  const Scalar last_v = static_cast<Scalar>(static_cast<double>(bms_replay_voltage_10uv[last]) * 1e-5);
  const Scalar last_i = static_cast<Scalar>(static_cast<double>(bms_replay_current_100ua[last]) * 1e-4);
  const std::uint64_t g0 = bms::target::platform_instructions();
  const bms::target::TickOutput after_gap = bms::target::catch_up_probe(fw, 600u, last_v, last_i);
  const std::uint64_t g1 = bms::target::platform_instructions();
  std::printf("# catch_up_probe gap 600 finite %u instructions %lu\n",
              std::isfinite(after_gap.z_v) ? 1u : 0u, static_cast<unsigned long>(g1 - g0));
  put_ticks("resync_ticks", resync_ticks, resyncs_seen);
  std::printf("# ticks %u\n", static_cast<unsigned>(kReplayTicks));
  std::printf("# scalar %s\n", sizeof(Scalar) == sizeof(double) ? "double" : "float");
  std::printf("# source_hash %s\n", BMS_FW_SOURCE_HASH);
  std::printf("# status_or 0x%08x\n", static_cast<unsigned>(status_or));
  std::printf("# newton_iterations_max %u (cap %d)\n", static_cast<unsigned>(newton_max),
              bms::target::Model::kMaxNewtonIterations);
  std::printf("# newton_cap_hits %u\n", static_cast<unsigned>(cap_hits));
  std::printf("# firmware_state_bytes %u\n", static_cast<unsigned>(sizeof(fw)));
  std::printf("# counter_overhead_instructions %lu\n", static_cast<unsigned long>(c1 - c0));
  bms::target::platform_report();
  return finite ? 0 : 1;
}
