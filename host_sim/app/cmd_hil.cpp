#include <memory>
#include <string>

#include <fmt/format.h>

#include "commands.hpp"
#include "hil/hil_session.hpp"
#include "io/input_error.hpp"
#include "simulate_options.hpp"

namespace bms::app {

namespace {

// The command line: the run's configuration and the flags that choose its profile.
struct HilCli {
  hil::HilConfig run;
  bool lockstep = true, beyond_paper = false;
  std::string settings = "best";
};

}  // namespace

Runner add_hil(CLI::App& app) {
  auto* sub = app.add_subcommand("hil", "Host-in-the-loop: the truth simulator feeds the firmware process over SocketCAN");
  auto c = std::make_shared<HilCli>();
  register_simulate_options(*sub, c->run.sim);
  sub->add_option("--bus", c->run.bus, "vcan0 (or any SocketCAN interface), or 'uml' to run inside a kernel with vcan")
      ->capture_default_str();
  sub->add_flag("--lockstep", c->lockstep, "Simulator-driven ticks, as fast as possible (default)");
  sub->add_flag("--realtime", c->run.realtime, "One measurement every 0.2 s of wall time; the firmware's timer ticks");
  sub->add_option("--h", c->run.overrides.h_v_per_ohm_m2.value,
                  "--settings paper: RCSI Markov parameter passed to the firmware (default: the paper's 0.01)");
  sub->add_option("--settings", c->settings,
                  "Estimator profile of the firmware: best (default), paper or nominal-growth, as `bmssim estimate "
                  "--settings`")
      ->capture_default_str();
  sub->add_flag("--beyond-paper", c->beyond_paper, "The same as --settings nominal-growth (its older name)");
  sub->add_option("--firmware", c->run.firmware, "Path of bms-firmware (default: beside bmssim in the build tree)");
  sub->add_option("--persist-every-s", c->run.persist_every_s,
                  "Firmware commits its state to NVM every this many seconds of ticks (and at each CC-charge end)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 86400.0));
  sub->add_option("--max-ticks", c->run.max_ticks, "Stop after this many ticks (0: the whole profile; truth.csv keeps the whole profile)")
      ->capture_default_str();
  sub->add_option("--fault", c->run.fault,
                  "Bus faults, lock-step only: comma-separated KEY=VALUE.\n"
                  "Rates (probability per tick): drop=P dup=P reorder=P crc=P length=P unknown=P seed=K.\n"
                  "Windows START:TICKS, START = tick or MODE+SECONDS (e.g. cc_charge+600):\n"
                  "burst= (frames lost) stale= (alive counter frozen) range= (7 V) nan= (voltage NaN)\n"
                  "busdown= (ip link down/up) kill= (firmware SIGKILLed, restarted after TICKS).\n"
                  "Example: --fault drop=0.01,crc=0.01,kill=cc_charge+600:25,seed=3");
  sub->add_option("--out", c->run.out, "Output folder (truth.csv, estimates.csv, summary.json, can.log)")->required();
  return [c, sub]() {
    // The firmware's profile and overrides, refused as bms-firmware refuses them (before any work).
    if (c->beyond_paper && sub->count("--settings") > 0)
      throw InputError("--beyond-paper is --settings nominal-growth; give one of them, not both");
    const std::string settings = c->beyond_paper ? "nominal-growth" : c->settings;
    if (!fw::parse_profile(settings.c_str(), c->run.profile))
      throw InputError("--settings must be 'best', 'paper' or 'nominal-growth' (got '" + settings + "')");
    c->run.overrides.h_v_per_ohm_m2.given = sub->count("--h") > 0;
    const fw::Refusal r = fw::unused_override(c->run.profile, c->run.overrides);
    if (r.option != nullptr)
      throw InputError(fmt::format("--{} is not used by --settings {}: {}", r.option, fw::profile_name(c->run.profile), r.reason));
    return hil::run_hil(c->run);
  };
}

}  // namespace bms::app
