// bmssim hil: the truth simulator feeds the firmware process (bms-firmware) over SocketCAN.
// Lock-step: the simulator owns the clock; one HOST_Measurement frame triggers one firmware
// tick, and the host waits for that tick's BMS_Status before the next (deterministic, as fast
// as the bus allows). Real time: one frame every 0.2 s of wall time.
// --bus uml re-runs this command inside a Linux kernel with vcan (scripts/vcan-run.sh).
#include <fcntl.h>
#include <signal.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "bms/fw/can_protocol.hpp"
#include "bms/hal/linux/socketcan.hpp"
#include "commands.hpp"
#include "estimation/estimate_output.hpp"
#include "estimation/estimate_run.hpp"
#include "io/candump_log.hpp"
#include "io/input_error.hpp"
#include "simulate_options.hpp"
#include "sim/truth_output.hpp"

extern char** environ;

namespace bms::app {

namespace {

namespace can = fw::can;

struct HilCli {
  SimulateOptions sim;
  std::string bus = "vcan0", out, firmware;
  bool lockstep = true, realtime = false;
  double h = 0.01;
};

std::filesystem::path default_firmware_path() {
  if (const char* e = std::getenv("BMS_FIRMWARE")) return e;
  std::error_code ec;
  const auto self = std::filesystem::read_symlink("/proc/self/exe", ec);
  return self.parent_path().parent_path() / "hal" / "bms-firmware";
}

CanLogEntry log_entry(double t_s, const std::string& iface, const hal::CanFrame& f) {
  CanLogEntry e;
  e.time_s = t_s;
  e.interface = iface;
  e.id = f.id & hal::kCanStdIdMask;
  e.dlc = f.len;
  for (int i = 0; i < f.len; ++i) e.data[static_cast<std::size_t>(i)] = f.data[i];
  return e;
}

class FirmwareProcess {
 public:
  FirmwareProcess(const std::filesystem::path& exe, const std::vector<std::string>& args) {
    if (!std::filesystem::exists(exe))
      throw InputError("firmware binary not found: " + exe.string() + " (build it: ./bms build, or set BMS_FIRMWARE)");
    int fds[2];
    if (pipe(fds) != 0) throw RuntimeFailure("pipe failed");
    posix_spawn_file_actions_t fa;
    posix_spawn_file_actions_init(&fa);
    posix_spawn_file_actions_adddup2(&fa, fds[1], STDOUT_FILENO);
    posix_spawn_file_actions_addclose(&fa, fds[0]);
    std::vector<char*> argv;
    std::string exe_s = exe.string();
    argv.push_back(exe_s.data());
    std::vector<std::string> copy = args;
    for (auto& a : copy) argv.push_back(a.data());
    argv.push_back(nullptr);
    const int rc = posix_spawn(&pid_, exe_s.c_str(), &fa, nullptr, argv.data(), environ);
    posix_spawn_file_actions_destroy(&fa);
    close(fds[1]);
    if (rc != 0) {
      close(fds[0]);
      throw RuntimeFailure("cannot start " + exe_s);
    }
    // Wait for "ready" (the firmware's socket is bound) or its exit.
    std::string line;
    char c = 0;
    while (read(fds[0], &c, 1) == 1 && c != '\n') line += c;
    close(fds[0]);
    if (line.find("ready") == std::string::npos) {
      int st = 0;
      waitpid(pid_, &st, 0);
      pid_ = -1;
      throw RuntimeFailure("the firmware process exited before it was ready (see its message above)");
    }
  }
  ~FirmwareProcess() { stop(); }
  int stop() {
    if (pid_ <= 0) return exit_code_;
    kill(pid_, SIGTERM);
    int st = 0;
    waitpid(pid_, &st, 0);
    pid_ = -1;
    exit_code_ = WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
    return exit_code_;
  }

 private:
  pid_t pid_ = -1;
  int exit_code_ = 0;
};

int run_hil(HilCli& c) {
  if (c.bus == "uml") {
    // Re-run inside a kernel with vcan0, same arguments but --bus vcan0.
    const std::filesystem::path runner = std::filesystem::path(BMS_SOURCE_DIR) / "scripts" / "vcan-run.sh";
    std::vector<std::string> args = {runner.string(), "--", "/proc/self/exe"};
    std::error_code ec;
    args.back() = std::filesystem::read_symlink("/proc/self/exe", ec).string();
    std::vector<char*> argv;
    for (auto& a : args) argv.push_back(a.data());
    std::vector<std::string> rest = {"hil", "--bus", "vcan0", "--out", std::filesystem::absolute(c.out).string(),
                                     "--cell", c.sim.cell, "--protocol", c.sim.protocol,
                                     "--cycles", std::to_string(c.sim.cycles), "--seed", std::to_string(c.sim.seed),
                                     "--current-a", fmt::format("{}", c.sim.current_a),
                                     "--noise-v-mv", fmt::format("{}", c.sim.noise_v_mv), "--noise-i-ma",
                                     fmt::format("{}", c.sim.noise_i_ma), "--ic-error-pct",
                                     fmt::format("{}", c.sim.ic_error_pct), "--h", fmt::format("{}", c.h)};
    for (const auto& e : c.sim.effects) {
      rest.push_back("--effect");
      rest.push_back(e);
    }
    if (!c.firmware.empty()) {
      rest.push_back("--firmware");
      rest.push_back(std::filesystem::absolute(c.firmware).string());
    }
    if (c.realtime) rest.push_back("--realtime");
    for (auto& a : rest) argv.push_back(a.data());
    argv.push_back(nullptr);
    execv(args[0].c_str(), argv.data());
    throw RuntimeFailure("cannot run " + args[0]);
  }
  std::fprintf(stderr, "hil: simulating the truth (%d cycles)...\n", c.sim.cycles);
  SimulateRun run = run_simulation(c.sim, {});
  // What goes on the bus: the measured values at the bus resolution (10 uV, 0.1 mA). The
  // truth.csv records exactly these, so `bmssim estimate` on it sees what the firmware saw.
  const std::size_t n = run.result.samples.size();
  for (std::size_t i = 0; i < n; ++i) {
    can::Measurement m;
    m.voltage_v = run.measured.voltage_v[i];
    m.current_a = run.measured.current_a[i];
    hal::CanFrame f{};
    can::encode(m, 0, f);
    can::Measurement back;
    can::decode(f, back);
    run.measured.voltage_v[i] = back.voltage_v;
    run.measured.current_a[i] = back.current_a;
  }
  const std::filesystem::path dir(c.out);
  std::filesystem::create_directories(dir);
  write_truth_csv(dir / "truth.csv", run.result, run.measured);

  hal::lnx::SocketCanBus bus;
  if (bus.open(c.bus.c_str()) != hal::Status::ok)
    throw RuntimeFailure("cannot open CAN interface " + c.bus + ": " + bus.last_error() +
                         " (on a machine without kernel CAN use --bus uml)");
  const std::filesystem::path nvm = dir / "firmware.nvm";
  std::filesystem::remove(nvm);
  std::vector<std::string> fw_args = {"--can", c.bus, c.realtime ? "--realtime" : "--lockstep", "--nvm", nvm.string(),
                                      "--h", fmt::format("{}", c.h)};
  FirmwareProcess fw(c.firmware.empty() ? default_firmware_path() : std::filesystem::path(c.firmware), fw_args);

  CandumpWriter log(dir / "can.log");
  const double t_epoch = 1700000000.0;  // fixed: lock-step logs are identical run to run
  can::Transmitter tx;
  can::Receiver rx(can::Node::host);
  EstimateResult res;
  res.rows.reserve(n);
  const auto wall0 = std::chrono::steady_clock::now();
  for (std::size_t k = 0; k < n; ++k) {
    const auto& s = run.result.samples[k];
    can::Measurement m;
    m.seq = static_cast<std::uint16_t>(k & can::kSeqMask);
    m.voltage_v = run.measured.voltage_v[k];
    m.current_a = run.measured.current_a[k];
    hal::CanFrame f{};
    tx.encode(m, f);
    if (c.realtime) std::this_thread::sleep_until(wall0 + std::chrono::milliseconds(static_cast<long>(200 * k)));
    if (bus.send(f) != hal::Status::ok) throw RuntimeFailure(std::string("CAN send failed: ") + bus.last_error());
    const double t_log = c.realtime ? t_epoch + std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count()
                                    : t_epoch + s.t_s;
    log.write(log_entry(t_log, c.bus, f));
    EstimateRow row{};
    row.t_s = s.t_s;
    row.cycle = s.cycle;
    row.r_film_true_ohm_m2 = s.r_film_ohm_m2;
    std::vector<double> theta(2, 0.0);
    bool done = false;
    while (!done) {
      hal::CanFrame r{};
      const hal::Status st = bus.receive(r, 2000);
      if (st == hal::Status::timeout)
        throw RuntimeFailure(fmt::format("the firmware did not answer tick {} within 2 s", k));
      if (st != hal::Status::ok) throw RuntimeFailure(std::string("CAN receive failed: ") + bus.last_error());
      log.write(log_entry(t_log, c.bus, r));
      can::RxMessage msg{};
      if (rx.accept(r, msg) != can::RxResult::accepted) continue;
      switch (msg.msg) {
        case can::Msg::estimate1:
          row.r_film_est_ohm_m2 = msg.estimate1.r_film_ohm_m2;
          row.mode = msg.estimate1.mode;
          row.rcsi_active = msg.estimate1.rcsi_active;
          break;
        case can::Msg::estimate2: theta[0] = msg.estimate2.theta0; break;
        case can::Msg::estimate3: theta[1] = msg.estimate3.theta1; break;
        case can::Msg::health:
          row.z_v = msg.health.z_v;
          row.li_loss_ah = msg.health.li_loss_ah;
          break;
        case can::Msg::status:
          row.status = msg.status.fault_bits;
          done = true;
          break;
        default: break;
      }
    }
    row.model_voltage_v = std::nan("");
    row.model_current_a = std::nan("");
    row.j_side_a_m3 = std::nan("");
    res.rows.push_back(row);
    res.theta_rows.push_back(theta);
    if (k % 20000 == 0) std::fprintf(stderr, "hil: tick %zu / %zu\n", k, n);
  }
  res.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  const int fw_exit = fw.stop();
  log.commit();
  res.theta = res.theta_rows.back();
  std::vector<fw::Mode> modes;
  for (const auto& s : run.result.samples) modes.push_back(s.mode);
  res.cycles = score_cycles(res.rows, true, modes);
  write_estimates_csv(dir / "estimates.csv", res);
  EstimateOptions eo;
  eo.h_v_per_ohm_m2 = c.h;
  auto summary = estimate_summary_json(res, eo);
  summary["simulation"] = summary_json(run.result);
  summary["simulation"]["options"] = options_json(c.sim);
  summary["hil"] = {{"bus", c.bus}, {"lockstep", !c.realtime}, {"ticks", n}, {"wall_s", res.wall_s},
                    {"sim_s_per_wall_s", run.result.sim_s / res.wall_s}, {"firmware_exit", fw_exit},
                    {"frames_dropped_by_host", rx.counters().dropped_total()}};
  write_file_atomically(dir / "summary.json", summary.dump(2) + "\n");
  std::fprintf(stderr, "hil: %zu ticks in %.2f s wall (%.0f x real time), firmware exit %d -> %s\n", n, res.wall_s,
               run.result.sim_s / res.wall_s, fw_exit, dir.c_str());
  for (const auto& cs : res.cycles)
    std::fprintf(stderr, "hil: cycle %d: film-resistance error in CC charge: median %.3f %%, end %.3f %%\n", cs.cycle,
                 cs.r_film_err_median_pct, cs.r_film_err_end_pct);
  return fw_exit == 0 ? 0 : 1;
}

}  // namespace

Runner add_hil(CLI::App& app) {
  auto* sub = app.add_subcommand("hil", "Host-in-the-loop: the truth simulator feeds the firmware process over SocketCAN");
  auto c = std::make_shared<HilCli>();
  register_simulate_options(*sub, c->sim);
  sub->add_option("--bus", c->bus, "vcan0 (or any SocketCAN interface), or 'uml' to run inside a kernel with vcan")
      ->capture_default_str();
  sub->add_flag("--lockstep", c->lockstep, "Simulator-driven ticks, as fast as possible (default)");
  sub->add_flag("--realtime", c->realtime, "One tick every 0.2 s of wall time");
  sub->add_option("--h", c->h, "RCSI Markov parameter passed to the firmware")->capture_default_str();
  sub->add_option("--firmware", c->firmware, "Path of bms-firmware (default: beside bmssim in the build tree)");
  sub->add_option("--out", c->out, "Output folder (truth.csv, estimates.csv, summary.json, can.log)")->required();
  return [c]() { return run_hil(*c); };
}

}  // namespace bms::app
