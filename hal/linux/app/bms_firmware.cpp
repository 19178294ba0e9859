// bms-firmware: the BMS firmware as a Linux process behind the HAL (SocketCAN, timerfd, a
// file as non-volatile memory). Same application and core as the board image.
//
//   bms-firmware --can vcan0 --lockstep|--realtime [--nvm FILE] [--h H] [--h-from-model]
//
// Lock-step: the host's HOST_Measurement frames trigger the ticks (deterministic, as fast
// as the host sends). Real time: a 0.2 s timerfd drives the ticks. SIGTERM or SIGINT: the
// state is saved to the NVM file and the process exits 0.
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <vector>

#include "bms/fw/bms_core.hpp"
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
               "  --can IFACE     SocketCAN interface (e.g. vcan0)\n"
               "  --lockstep      ticks triggered by the host's HOST_Measurement frames (deterministic)\n"
               "  --realtime      ticks from a 0.2 s timer\n"
               "  --nvm FILE      keep the estimator state in FILE (two slots, CRC); restored at start\n"
               "  --h H           RCSI Markov parameter [V per ohm m2] (default 0.01, the paper's)\n"
               "  --h-from-model  H from the model at each charge start\n"
               "exit codes: 0 stopped by SIGTERM/SIGINT, 1 runtime failure, 2 bad arguments\n");
}

}  // namespace

int main(int argc, char** argv) {
  std::string iface, nvm_path;
  bool lockstep = false, realtime = false, h_from_model = false;
  double h = 0.01;
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
    else if (a == "--h") {
      const std::string v = value("--h");
      char* end = nullptr;
      h = std::strtod(v.c_str(), &end);
      if (end == v.c_str() || *end != '\0' || h == 0.0) {
        std::fprintf(stderr, "bms-firmware: --h must be a nonzero number (got '%s')\n", v.c_str());
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
  Core::Config cfg;
  cfg.estimator.markov_v_per_ohm_m2 = h;
  cfg.markov_from_model = h_from_model;
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
  ao.tick_timeout_ms = 200;
  static App app(core, *bus, *ticks, log, *nvm, ao);
  app.restore_from_nvm();
  // The host waits for this line before its first frame (a frame sent before the socket
  // is bound would be lost).
  std::printf("bms-firmware: ready\n");
  std::fflush(stdout);
  while (g_stop == 0) {
    const bms::hal::Status s = app.step();
    if (s == bms::hal::Status::ok || s == bms::hal::Status::timeout) continue;
    if (g_stop != 0) break;  // a signal interrupted the wait
    std::fprintf(stderr, "bms-firmware: bus or timer failed: %s\n", bms::hal::status_name(s));
    app.persist();
    return 1;
  }
  app.persist();
  return 0;
}
