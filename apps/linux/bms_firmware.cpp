// bms-firmware: the BMS firmware as a Linux process behind the HAL (SocketCAN, timerfd, a
// file as non-volatile memory). The Linux entry point: it parses the flags, opens the drivers,
// builds the configuration (bms/fw/config/make_config.hpp) and runs the application
// (firmware/app: bms::app::BmsApplication), the same class the board image runs.
//
//   bms-firmware --can vcan0 --lockstep|--realtime [--nvm FILE] [--h H] [--h-from-model]
//                [--persist-every-s S] [--flash-endurance-cycles N] [--flash-lifetime-years Y]
//                [--rcvbuf-bytes N]
//
// Lock-step: the host's HOST_Measurement frames trigger the ticks (deterministic, as fast
// as the host sends). Real time: a 0.2 s timerfd drives the ticks. SIGTERM or SIGINT: the
// state is saved to the NVM file (within the write budget) and the process exits 0. The
// state is also committed at the end of every constant-current charge (the estimate just
// learned) and every S seconds of ticks, each within the flash write budget
// (firmware/include/bms/fw/nvm/nvm_budget.hpp: by default 10 000 cycles over 10 years, one
// commit per 4.4 h on average, 4 back to back).
// A failing bus (interface down) is not fatal: the error is logged and counted, and the
// firmware keeps waiting for frames, as a BMS on a vehicle bus must.
#include <sys/socket.h>
#include <unistd.h>

#include <cerrno>
#include <csignal>
#include <cstdio>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <string>

#include "bms/fw/estimation/bms_core.hpp"
#include "bms/app/bms_application.hpp"
#include "bms/fw/config/make_config.hpp"
#include "bms/hal/linux/file_nvm.hpp"
#include "bms/hal/linux/linux_clock.hpp"
#include "bms/hal/linux/process_watchdog.hpp"
#include "bms/hal/linux/socketcan.hpp"
#include "bms/hal/linux/stderr_log.hpp"
#include "bms/hal/linux/timerfd_tick.hpp"
#include "bms/hal/ram_nvm.hpp"
#include "bms/hal/lockstep.hpp"

namespace {

volatile std::sig_atomic_t g_stop = 0;  // set by the signal handler only
void on_signal(int) { g_stop = 1; }


void usage(FILE* to) {
  std::fprintf(to,
               "usage: bms-firmware --can IFACE (--lockstep | --realtime) [--nvm FILE] [--h H] [--h-from-model]\n"
               "                    [--settings best|paper|nominal-growth]\n"
               "                    [--persist-every-s S] [--flash-endurance-cycles N] [--flash-lifetime-years Y]\n"
               "                    [--rcvbuf-bytes N]\n"
               "  --can IFACE          SocketCAN interface (e.g. vcan0)\n"
               "  --lockstep           ticks triggered by the host's HOST_Measurement frames (deterministic)\n"
               "  --realtime           ticks from a 0.2 s timer\n"
               "  --nvm FILE           keep the estimator state in FILE (two slots, CRC); restored at start\n"
               "  --settings P         estimator profile (bms/fw/config/make_config.hpp): best (default; the nominal cell\n"
               "                       only: film, growth gain and lithium inventory identified together), paper\n"
               "                       (the paper's RCSI) or nominal-growth (RCSI with H from the model, state\n"
               "                       re-synchronisation, 600 s warm-up, bias calibration at the nominal initial\n"
               "                       film, charge-averaged estimate carried by the nominal growth law)\n"
               "  --beyond-paper       the same as --settings nominal-growth (its older name)\n"
               "  --h H                with --settings paper: RCSI Markov parameter [V per ohm m2] (default: the\n"
               "                       paper's 0.01); refused where the profile takes H from the model\n"
               "  --h-from-model       with --settings paper: H from the model at each charge start\n"
               "  --persist-every-s S  commit the state every S s of ticks (default: the budget's interval;\n"
               "                       0: only at the end of each CC charge and at exit), within the budget\n"
               "  --flash-endurance-cycles N  program/erase cycles the NVM is rated for (default 10000); with\n"
               "                       --flash-lifetime-years Y (default 10) this sets the write budget: on\n"
               "                       average one commit per Y years / (2 N), at most 4 back to back\n"
               "  --rcvbuf-bytes N     socket receive buffer (default 8388608: a replay sent faster than\n"
               "                       the ticks run queues in the kernel instead of being dropped)\n"
               "On exit the receive counters are printed on stderr as one line of key=value.\n"
               "exit codes: 0 stopped by SIGTERM/SIGINT, 1 runtime failure, 2 bad arguments\n");
}

bool parse_number(const std::string& text, double& out) {
  char* end = nullptr;
  out = std::strtod(text.c_str(), &end);
  return end != text.c_str() && *end == '\0' && std::isfinite(out);
}

// The kernel caps SO_RCVBUF at net.core.rmem_max; as root SO_RCVBUFFORCE passes the cap.
// Not fatal when both fail: lock-step traffic needs only a few frames of buffer.
void enlarge_receive_buffer(int fd, int bytes) {
  if (setsockopt(fd, SOL_SOCKET, SO_RCVBUFFORCE, &bytes, sizeof bytes) == 0) return;
  if (setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &bytes, sizeof bytes) != 0)
    std::fprintf(stderr, "bms-firmware: cannot set the socket receive buffer to %d bytes (errno %d)\n", bytes, errno);
}

struct Args {
  std::string iface, nvm_path;
  bool lockstep = false, realtime = false;
  bms::fw::Profile profile = bms::fw::Profile::best;
  bool profile_given = false;
  bms::fw::Overrides overrides;
  double persist_every_s = -1.0, rcvbuf_bytes = 8388608.0;
  double endurance_cycles = 10000.0, lifetime_years = 10.0;
};

[[noreturn]] void bad_argument(const char* what, const std::string& got) {
  std::fprintf(stderr, "bms-firmware: %s (got '%s')\n", what, got.c_str());
  std::exit(2);
}

// A number flag within [lo, hi]; exits 2 naming the flag otherwise.
double number_in(const std::string& v, double lo, double hi, const char* what) {
  double x = 0.0;
  if (!parse_number(v, x) || x < lo || x > hi) bad_argument(what, v);
  return x;
}

Args parse_args(int argc, char** argv) {
  Args a;
  for (int i = 1; i < argc; ++i) {
    const std::string f = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "bms-firmware: %s needs a value\n", f.c_str());
        std::exit(2);
      }
      return argv[++i];
    };
    if (f == "--can") {
      a.iface = value();
      // The kernel's limit (IFNAMSIZ = 16 with the terminating NUL): a bad argument, not a runtime failure.
      if (a.iface.empty() || a.iface.size() >= 16 || a.iface.find('/') != std::string::npos)
        bad_argument("--can must name a CAN interface of 1..15 characters without '/'", a.iface);
    }
    else if (f == "--nvm") a.nvm_path = value();
    else if (f == "--lockstep") a.lockstep = true;
    else if (f == "--realtime") a.realtime = true;
    else if (f == "--h-from-model") a.overrides.h_from_model = true;
    else if (f == "--beyond-paper" || f == "--settings") {
      const std::string v = f == "--settings" ? value() : "nominal-growth";
      if (a.profile_given) bad_argument("give one of --settings and --beyond-paper, once", v);
      if (!bms::fw::parse_profile(v.c_str(), a.profile))
        bad_argument("--settings must be 'best', 'paper' or 'nominal-growth'", v);
      a.profile_given = true;
    } else if (f == "--h") {
      const std::string v = value();
      double h = 0.0;
      if (!parse_number(v, h) || h == 0.0) bad_argument("--h must be a nonzero number", v);
      a.overrides.h_v_per_ohm_m2 = h;
    } else if (f == "--persist-every-s") a.persist_every_s = number_in(value(), 0.0, 86400.0, "--persist-every-s must be 0..86400");
    else if (f == "--flash-endurance-cycles")
      a.endurance_cycles = number_in(value(), 100.0, 1e12, "--flash-endurance-cycles must be 100..1e12");
    else if (f == "--flash-lifetime-years")
      a.lifetime_years = number_in(value(), 0.01, 100.0, "--flash-lifetime-years must be 0.01..100");
    else if (f == "--rcvbuf-bytes")
      a.rcvbuf_bytes = number_in(value(), 1024.0, 1073741824.0, "--rcvbuf-bytes must be 1024..1073741824");
    else if (f == "--help" || f == "-h") {
      usage(stdout);
      std::exit(0);
    } else {
      std::fprintf(stderr, "bms-firmware: unknown argument '%s'\n", f.c_str());
      usage(stderr);
      std::exit(2);
    }
  }
  if (a.iface.empty() || a.lockstep == a.realtime) {
    std::fprintf(stderr, "bms-firmware: give --can IFACE and exactly one of --lockstep / --realtime\n");
    usage(stderr);
    std::exit(2);
  }
  const bms::fw::Refusal r = bms::fw::unused_override(a.profile, a.overrides);
  if (r.option != nullptr) {
    std::fprintf(stderr, "bms-firmware: --%s is not used by --settings %s: %s\n", r.option,
                 bms::fw::profile_name(a.profile), r.reason);
    std::exit(2);
  }
  return a;
}

using Model = bms::fw::ReducedCell<double>;
using Core = bms::fw::BmsCore<double, Model, 1, 0>;
using App = bms::app::BmsApplication<Core>;

// The estimator's configuration: a profile of the nominal cell with the overrides (make_config;
// parse_args has refused an override the profile does not use).
Core::Config config_for(const Args& a) {
  Core::Config cfg{};
  const bms::fw::Refusal r = bms::fw::make_config<Core>(bms::fw::paper_nominal_cell<double>(), a.profile, a.overrides, cfg);
  if (r.option != nullptr) bad_argument(r.reason, std::string("--") + r.option);
  return cfg;
}

App::Options app_options(const Args& a, double dt_s) {
  App::Options ao;
  ao.lockstep = a.lockstep;
  ao.tick_timeout_ms = 200;
  ao.budget.endurance_cycles = a.endurance_cycles;
  ao.budget.lifetime_s = a.lifetime_years * 365.25 * 86400.0;
  ao.budget.tick_s = dt_s;
  const std::uint32_t budget_ticks = bms::fw::nvm::WriteBudget::interval_for(ao.budget);
  ao.persist_every_ticks =
      a.persist_every_s < 0.0 ? budget_ticks : static_cast<std::uint32_t>(std::lround(a.persist_every_s / dt_s));
  std::fprintf(stderr, "bms-firmware: NVM write budget: one commit per %.0f s on average (%.0f cycles, %.1f years)\n",
               budget_ticks * dt_s, a.endurance_cycles, a.lifetime_years);
  return ao;
}

// Runs ticks until SIGTERM/SIGINT; a bus that goes down is retried, any other failure ends
// the run (exit 1). The state is committed on the way out.
int run(App& app, const bms::hal::lnx::SocketCanBus& can, unsigned long& bus_errors) {
  while (g_stop == 0) {
    const bms::hal::Status s = app.step();
    if (s == bms::hal::Status::ok || s == bms::hal::Status::timeout) continue;
    if (g_stop != 0) break;  // a signal interrupted the wait
    if (s != bms::hal::Status::io_error) {
      std::fprintf(stderr, "bms-firmware: bus or timer failed: %s\n", bms::hal::status_name(s));
      app.persist();
      return 1;
    }
    // The interface went down (ENETDOWN) or the timer hiccuped: wait and carry on.
    if (bus_errors++ % 50 == 0)
      std::fprintf(stderr, "bms-firmware: bus error (%s: %s), retrying\n", bms::hal::status_name(s), can.last_error());
    usleep(20000);
  }
  app.persist();
  return 0;
}

void print_counters(const App& app, unsigned long bus_errors) {
  const auto& rc = app.receiver().counters();
  std::fprintf(stderr,
               "bms-firmware: counters accepted=%u ignored_id=%u dropped_length=%u dropped_crc=%u dropped_counter=%u "
               "dropped_seq=%u lost_frames=%u stale_events=%u bus_errors=%lu nvm_commits=%u nvm_failures=%u "
               "nvm_refused_by_budget=%u\n",
               rc.accepted, rc.ignored_id, rc.dropped_length, rc.dropped_crc, rc.dropped_counter, rc.dropped_seq,
               rc.lost_frames, rc.stale_events, bus_errors, app.nvm_counters().commits, app.nvm_counters().failures,
               app.nvm_counters().refused_by_budget);
}

bool classify_tick(const bms::hal::CanFrame& f, std::uint32_t& t, void* c) {
  return static_cast<bms::fw::can::LockstepTicks*>(c)->classify(f, t);
}

}  // namespace

int main(int argc, char** argv) {
  const Args args = parse_args(argc, argv);
  std::signal(SIGTERM, on_signal);
  std::signal(SIGINT, on_signal);

  bms::hal::lnx::StderrLogSink log;
  bms::hal::lnx::SocketCanBus can;
  if (can.open(args.iface.c_str()) != bms::hal::Status::ok) {
    std::fprintf(stderr, "bms-firmware: cannot open CAN interface %s: %s\n", args.iface.c_str(), can.last_error());
    return 1;
  }
  enlarge_receive_buffer(can.native_handle(), static_cast<int>(args.rcvbuf_bytes));
  bms::hal::lnx::FileNvm file_nvm;
  // Without --nvm: the state lives as long as the process (erased RAM, as a blank flash).
  static std::uint8_t ram_bytes[16384];
  static bms::hal::RamNvm ram_nvm(ram_bytes, sizeof ram_bytes, 256u);
  (void)ram_nvm.erase(0, sizeof ram_bytes);
  bms::hal::NonVolatileMemory* nvm = &ram_nvm;
  if (!args.nvm_path.empty()) {
    if (file_nvm.open(args.nvm_path.c_str(), 16384, 256) != bms::hal::Status::ok) {
      std::fprintf(stderr, "bms-firmware: cannot open NVM file %s: %s\n", args.nvm_path.c_str(), file_nvm.last_error());
      return 1;
    }
    nvm = &file_nvm;
  }
  static Model model;  // static storage: the firmware's objects are not on the stack
  model.init_default();
  const Core::Config cfg = config_for(args);
  static Core core(cfg, model);

  static bms::fw::can::LockstepTicks ticks_classifier;
  static bms::hal::LockstepBus<64> lockstep_bus(can, classify_tick, &ticks_classifier);
  static bms::hal::lnx::TimerfdTickSource timer;
  bms::hal::CanBus* bus = &can;
  bms::hal::TickSource* ticks = &timer;
  if (args.lockstep) {
    bus = &lockstep_bus;
    ticks = &lockstep_bus;
  } else if (timer.open() != bms::hal::Status::ok) {
    std::fprintf(stderr, "bms-firmware: cannot start the tick timer: %s\n", timer.last_error());
    return 1;
  }
  static bms::hal::lnx::LinuxMonotonicClock clock;
  static bms::hal::lnx::ProcessWatchdog watchdog;
  App::Options ao = app_options(args, cfg.dt_s);
  ao.lockstep_ticks = &ticks_classifier;
  ao.watchdog = &watchdog;
  ao.clock = &clock;
  static App app(core, *bus, *ticks, log, *nvm, ao);
  app.restore_from_nvm();
  // The host waits for this line before its first frame (a frame sent before the socket
  // is bound would be lost).
  std::printf("bms-firmware: ready\n");
  std::fflush(stdout);
  unsigned long bus_errors = 0;
  const int rc = run(app, can, bus_errors);
  if (rc == 0) print_counters(app, bus_errors);
  return rc;
}
