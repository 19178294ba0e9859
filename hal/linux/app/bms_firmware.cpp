// bms-firmware: the BMS firmware as a Linux process behind the HAL (SocketCAN, timerfd, a
// file as non-volatile memory). Same application and core as the board image.
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
// (firmware/include/bms/fw/nvm_budget.hpp: by default 10 000 cycles over 10 years, one
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
#include <vector>

#include "bms/fw/bms_core.hpp"
#include "bms/fw/paper_cell_profiles.hpp"
#include "bms/hal/bms_application.hpp"
#include "bms/hal/linux/file_nvm.hpp"
#include "bms/hal/linux/socketcan.hpp"
#include "bms/hal/linux/stderr_log.hpp"
#include "bms/hal/linux/timerfd_tick.hpp"
#include "bms/hal/lockstep.hpp"

namespace {

volatile std::sig_atomic_t g_stop = 0;  // set by the signal handler only
void on_signal(int) { g_stop = 1; }

// Volatile NVM for runs without --nvm: the state lives as long as the process.
class RamOnlyNvm final : public bms::hal::NonVolatileMemory {
 public:
  RamOnlyNvm() : bytes_(kSize, 0xFF) {}
  std::size_t size_bytes() const override { return kSize; }
  std::size_t page_size() const override { return 256; }
  bms::hal::Status read(std::size_t off, void* dst, std::size_t len) override {
    if (off + len > kSize) return bms::hal::Status::out_of_range;
    std::memcpy(dst, bytes_.data() + off, len);
    return bms::hal::Status::ok;
  }
  bms::hal::Status write(std::size_t off, const void* src, std::size_t len) override {
    if (off + len > kSize) return bms::hal::Status::out_of_range;
    std::memcpy(bytes_.data() + off, src, len);
    return bms::hal::Status::ok;
  }
  bms::hal::Status erase(std::size_t off, std::size_t len) override {
    if (off + len > kSize) return bms::hal::Status::out_of_range;
    std::memset(bytes_.data() + off, 0xFF, len);
    return bms::hal::Status::ok;
  }

 private:
  static constexpr std::size_t kSize = 16384;
  std::vector<unsigned char> bytes_;
};

void usage(FILE* to) {
  std::fprintf(to,
               "usage: bms-firmware --can IFACE (--lockstep | --realtime) [--nvm FILE] [--h H] [--h-from-model]\n"
               "                    [--settings best|paper] [--beyond-paper]\n"
               "                    [--persist-every-s S] [--flash-endurance-cycles N] [--flash-lifetime-years Y]\n"
               "                    [--rcvbuf-bytes N]\n"
               "  --can IFACE          SocketCAN interface (e.g. vcan0)\n"
               "  --lockstep           ticks triggered by the host's HOST_Measurement frames (deterministic)\n"
               "  --realtime           ticks from a 0.2 s timer\n"
               "  --nvm FILE           keep the estimator state in FILE (two slots, CRC); restored at start\n"
               "  --settings P         estimator profile: best (default; the nominal cell only: film, growth gain\n"
               "                       and lithium inventory identified together) or paper (the paper's RCSI)\n"
               "  --h H                with --settings paper: RCSI Markov parameter [V per ohm m2] (default 0.01)\n"
               "  --h-from-model       H from the model at each charge start\n"
               "  --beyond-paper       session 5's profile (as bmssim estimate --beyond-paper): H from the model,\n"
               "                       state re-synchronisation, 600 s warm-up, bias calibration at the nominal\n"
               "                       initial film, charge-averaged estimate propagated by the nominal growth law\n"
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

}  // namespace

int main(int argc, char** argv) {
  std::string iface, nvm_path;
  bool lockstep = false, realtime = false, h_from_model = false, beyond_paper = false;
  std::string settings = "best";
  double h = 0.01, persist_every_s = -1.0, rcvbuf_bytes = 8388608.0;
  double endurance_cycles = 10000.0, lifetime_years = 10.0;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&](const char* name) -> std::string {
      if (i + 1 >= argc) {
        std::fprintf(stderr, "bms-firmware: %s needs a value\n", name);
        std::exit(2);
      }
      return argv[++i];
    };
    if (a == "--can") iface = value("--can");
    else if (a == "--nvm") nvm_path = value("--nvm");
    else if (a == "--lockstep") lockstep = true;
    else if (a == "--realtime") realtime = true;
    else if (a == "--h-from-model") h_from_model = true;
    else if (a == "--beyond-paper") beyond_paper = true;
    else if (a == "--settings") {
      settings = value("--settings");
      if (settings != "best" && settings != "paper") {
        std::fprintf(stderr, "bms-firmware: --settings must be 'best' or 'paper' (got '%s')\n", settings.c_str());
        return 2;
      }
    }
    else if (a == "--h") {
      const std::string v = value("--h");
      if (!parse_number(v, h) || h == 0.0) {
        std::fprintf(stderr, "bms-firmware: --h must be a nonzero number (got '%s')\n", v.c_str());
        return 2;
      }
    } else if (a == "--persist-every-s") {
      const std::string v = value("--persist-every-s");
      if (!parse_number(v, persist_every_s) || persist_every_s < 0.0 || persist_every_s > 86400.0) {
        std::fprintf(stderr, "bms-firmware: --persist-every-s must be 0..86400 (got '%s')\n", v.c_str());
        return 2;
      }
    } else if (a == "--flash-endurance-cycles") {
      const std::string v = value("--flash-endurance-cycles");
      if (!parse_number(v, endurance_cycles) || endurance_cycles < 100.0 || endurance_cycles > 1e12) {
        std::fprintf(stderr, "bms-firmware: --flash-endurance-cycles must be 100..1e12 (got '%s')\n", v.c_str());
        return 2;
      }
    } else if (a == "--flash-lifetime-years") {
      const std::string v = value("--flash-lifetime-years");
      if (!parse_number(v, lifetime_years) || lifetime_years < 0.01 || lifetime_years > 100.0) {
        std::fprintf(stderr, "bms-firmware: --flash-lifetime-years must be 0.01..100 (got '%s')\n", v.c_str());
        return 2;
      }
    } else if (a == "--rcvbuf-bytes") {
      const std::string v = value("--rcvbuf-bytes");
      if (!parse_number(v, rcvbuf_bytes) || rcvbuf_bytes < 1024.0 || rcvbuf_bytes > 1073741824.0) {
        std::fprintf(stderr, "bms-firmware: --rcvbuf-bytes must be 1024..1073741824 (got '%s')\n", v.c_str());
        return 2;
      }
    } else if (a == "--help" || a == "-h") {
      usage(stdout);
      return 0;
    } else {
      std::fprintf(stderr, "bms-firmware: unknown argument '%s'\n", a.c_str());
      usage(stderr);
      return 2;
    }
  }
  if (iface.empty() || lockstep == realtime) {
    std::fprintf(stderr, "bms-firmware: give --can IFACE and exactly one of --lockstep / --realtime\n");
    usage(stderr);
    return 2;
  }
  std::signal(SIGTERM, on_signal);
  std::signal(SIGINT, on_signal);

  bms::hal::lnx::StderrLogSink log;
  bms::hal::lnx::SocketCanBus can;
  if (can.open(iface.c_str()) != bms::hal::Status::ok) {
    std::fprintf(stderr, "bms-firmware: cannot open CAN interface %s: %s\n", iface.c_str(), can.last_error());
    return 1;
  }
  enlarge_receive_buffer(can.native_handle(), static_cast<int>(rcvbuf_bytes));
  bms::hal::lnx::FileNvm file_nvm;
  RamOnlyNvm ram_nvm;
  bms::hal::NonVolatileMemory* nvm = &ram_nvm;
  if (!nvm_path.empty()) {
    if (file_nvm.open(nvm_path.c_str(), 16384, 256) != bms::hal::Status::ok) {
      std::fprintf(stderr, "bms-firmware: cannot open NVM file %s: %s\n", nvm_path.c_str(), file_nvm.last_error());
      return 1;
    }
    nvm = &file_nvm;
  }

  using Model = bms::fw::ReducedCell<double>;
  using Core = bms::fw::BmsCore<double, Model, 1, 0>;
  static Model model;  // static storage: the firmware's objects are not on the stack
  model.init_default();
  using Cell = bms::fw::PaperCellTraits;
  Core::Config cfg =
      beyond_paper ? Core::beyond_paper_config(Model::inventory_of(Cell::kNeg.stoich_init, Cell::kPos.stoich_init),
                                               Model::nominal_film_growth_ohm_m2_per_a_m3_s())
                   : bms::fw::paper_cell_config<Core>(settings == "paper" ? bms::fw::Profile::paper : bms::fw::Profile::best);
  if (!beyond_paper && settings == "paper") {
    cfg.estimator.markov_v_per_ohm_m2 = h;
    cfg.markov_from_model = h_from_model;
  }
  // Plausibility window of the measured voltage: the paper cell's limits with 0.5 V margin,
  // so a sensor reading of 0 V (what a NaN becomes on the bus) is rejected, not modelled.
  cfg.voltage_min_v = bms::fw::paper::kLowerVoltage_v - 0.5;
  cfg.voltage_max_v = bms::fw::paper::kUpperVoltage_v + 0.5;
  static Core core(cfg, model);

  bms::fw::can::LockstepTicks ticks_classifier;
  bms::hal::LockstepBus<64> lockstep_bus(
      can, [](const bms::hal::CanFrame& f, std::uint32_t& t, void* c) {
        return static_cast<bms::fw::can::LockstepTicks*>(c)->classify(f, t);
      },
      &ticks_classifier);
  bms::hal::lnx::TimerfdTickSource timer;
  bms::hal::CanBus* bus = &can;
  bms::hal::TickSource* ticks = &timer;
  if (lockstep) {
    bus = &lockstep_bus;
    ticks = &lockstep_bus;
  } else if (timer.open() != bms::hal::Status::ok) {
    std::fprintf(stderr, "bms-firmware: cannot start the tick timer: %s\n", timer.last_error());
    return 1;
  }
  using App = bms::hal::BmsApplication<Core>;
  App::Options ao;
  ao.lockstep = lockstep;
  ao.lockstep_ticks = &ticks_classifier;
  ao.tick_timeout_ms = 200;
  ao.budget.endurance_cycles = endurance_cycles;
  ao.budget.lifetime_s = lifetime_years * 365.25 * 86400.0;
  ao.budget.tick_s = cfg.dt_s;
  const std::uint32_t budget_ticks = bms::fw::nvm::WriteBudget::interval_for(ao.budget);
  ao.persist_every_ticks = persist_every_s < 0.0 ? budget_ticks
                                                 : static_cast<std::uint32_t>(std::lround(persist_every_s / cfg.dt_s));
  std::fprintf(stderr, "bms-firmware: NVM write budget: one commit per %.0f s on average (%.0f cycles, %.1f years)\n",
               budget_ticks * cfg.dt_s, endurance_cycles, lifetime_years);
  static App app(core, *bus, *ticks, log, *nvm, ao);
  app.restore_from_nvm();
  // The host waits for this line before its first frame (a frame sent before the socket
  // is bound would be lost).
  std::printf("bms-firmware: ready\n");
  std::fflush(stdout);
  unsigned long bus_errors = 0;
  while (g_stop == 0) {
    const bms::hal::Status s = app.step();
    if (s == bms::hal::Status::ok) continue;
    if (s == bms::hal::Status::timeout) continue;
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
  const auto& rc = app.receiver().counters();
  std::fprintf(stderr,
               "bms-firmware: counters accepted=%u ignored_id=%u dropped_length=%u dropped_crc=%u dropped_counter=%u "
               "dropped_seq=%u lost_frames=%u stale_events=%u bus_errors=%lu nvm_commits=%u nvm_failures=%u "
               "nvm_refused_by_budget=%u\n",
               rc.accepted, rc.ignored_id, rc.dropped_length, rc.dropped_crc, rc.dropped_counter, rc.dropped_seq,
               rc.lost_frames, rc.stale_events, bus_errors, app.nvm_counters().commits, app.nvm_counters().failures,
               app.nvm_counters().refused_by_budget);
  return 0;
}
