#pragma once
// One host-in-the-loop run (`bmssim hil`): the truth simulated on the bus's grid, the firmware
// process fed over SocketCAN (or the whole run re-started inside User-Mode Linux for --bus uml),
// the fault plan, and the run's folder (truth.csv, estimates.csv, summary.json, can.log).
#include <cstddef>
#include <string>

#include "bms/fw/config/make_config.hpp"
#include "sim/simulation_plan.hpp"

namespace bms::hil {

struct HilConfig {
  SimulateOptions sim;
  std::string bus = "vcan0", out, firmware, fault;  // firmware: "" = beside bmssim in the build tree
  bool realtime = false;                           // false: lock-step
  fw::Profile profile = fw::Profile::best;
  fw::Overrides overrides;  // --h: passed to the firmware only when given
  double persist_every_s = 60.0;
  std::size_t max_ticks = 0;  // 0: the whole profile
};

// Runs it; every option is checked before the bus or a kernel is touched (InputError). Returns
// 0, or the exit code of the run inside UML; throws RuntimeFailure, or Interrupted on a signal
// (nothing of the run left behind).
int run_hil(const HilConfig& c);

}  // namespace bms::hil
