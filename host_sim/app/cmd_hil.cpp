// bmssim hil: the truth simulator feeds the firmware process (bms-firmware) over SocketCAN.
// Lock-step: the simulator owns the clock; the frames of one tick are sent, and the host
// waits for one BMS_Status per tick trigger among them (deterministic, as fast as the bus
// allows). Real time: one measurement every 0.2 s of wall time; the firmware's own timer
// ticks. --fault injects bus faults into the measurement stream (host_sim/src/hil/fault_plan.hpp).
// --bus uml re-runs this command inside a Linux kernel with vcan (scripts/vcan-run.sh).
#include <fcntl.h>
#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
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
#include "hil/fault_plan.hpp"
#include "hil/firmware_process.hpp"
#include "hil/staged_output.hpp"
#include "io/atomic_file.hpp"
#include "io/candump_log.hpp"
#include "io/input_error.hpp"
#include "simulate_options.hpp"
#include "sim/truth_output.hpp"

extern char** environ;

namespace bms::app {

namespace {

namespace can = fw::can;

// estimates.csv status column: bits 0..7 are the firmware's FaultBits; this host bit marks
// a tick the firmware did not answer (killed, or the bus down): the row holds the last answer.
constexpr std::uint32_t kHostNoAnswer = 1u << 8;
// ... and this one a tick whose frames were all repeats or late (duplicated, reordered), so
// they triggered no firmware tick: nothing was asked, the row holds the last answer.
constexpr std::uint32_t kHostNotAsked = 1u << 9;

struct HilCli {
  SimulateOptions sim;
  std::string bus = "vcan0", out, firmware, fault;
  bool lockstep = true, realtime = false, beyond_paper = false;
  std::string settings = "best";
  double h = 0.01, persist_every_s = 60.0;
  std::size_t max_ticks = 0;
};

CanLogEntry log_entry(double t_s, const std::string& iface, const hal::CanFrame& f) {
  CanLogEntry e;
  e.time_s = t_s;
  e.interface = iface;
  e.id = f.id & hal::kCanStdIdMask;
  e.dlc = f.len;
  for (int i = 0; i < f.len; ++i) e.data[static_cast<std::size_t>(i)] = f.data[i];
  return e;
}

// Re-runs this very command line inside a kernel with vcan0: the arguments as given,
// --bus uml replaced by --bus vcan0 (the guest keeps the working directory and environment).
[[noreturn]] void exec_in_uml() {
  std::ifstream in("/proc/self/cmdline", std::ios::binary);
  std::vector<std::string> args;
  for (std::string a; std::getline(in, a, '\0');) args.push_back(a);
  if (args.empty()) throw RuntimeFailure("cannot read /proc/self/cmdline");
  std::error_code ec;
  args[0] = std::filesystem::read_symlink("/proc/self/exe", ec).string();
  for (std::size_t i = 1; i < args.size(); ++i) {
    if (args[i] == "--bus" && i + 1 < args.size()) args[i + 1] = "vcan0";
    if (args[i] == "--bus=uml") args[i] = "--bus=vcan0";
  }
  const std::string runner = (std::filesystem::path(BMS_SOURCE_DIR) / "scripts" / "vcan-run.sh").string();
  args.insert(args.begin(), {runner, "--"});
  std::vector<char*> argv;
  for (auto& a : args) argv.push_back(a.data());
  argv.push_back(nullptr);
  execv(runner.c_str(), argv.data());
  throw RuntimeFailure("cannot run " + runner);
}

// `ip link set IFACE up|down` (the bus going away and coming back).
void set_link(const std::string& iface, const char* state) {
  std::vector<std::string> a = {"ip", "link", "set", iface, state};
  std::vector<char*> argv;
  for (auto& s : a) argv.push_back(s.data());
  argv.push_back(nullptr);
  pid_t pid = -1;
  if (posix_spawnp(&pid, "ip", nullptr, nullptr, argv.data(), environ) != 0)
    throw RuntimeFailure("cannot run ip link set " + iface + " " + state);
  int st = 0;
  waitpid(pid, &st, 0);
  if (!WIFEXITED(st) || WEXITSTATUS(st) != 0) throw RuntimeFailure("ip link set " + iface + " " + state + " failed");
}

// Receive counters of BMS_RxStats come mod 256: the host adds up the differences.
struct RxTotals {
  std::uint64_t drop_length = 0, drop_crc = 0, drop_counter = 0, ignored_ids = 0, lost_frames = 0;
  can::BmsRxStats last{};
  void add(const can::BmsRxStats& s) {
    auto d = [](std::uint8_t now, std::uint8_t before) { return static_cast<std::uint8_t>(now - before); };
    drop_length += d(s.drop_length, last.drop_length);
    drop_crc += d(s.drop_crc, last.drop_crc);
    drop_counter += d(s.drop_counter, last.drop_counter);
    ignored_ids += d(s.ignored_ids, last.ignored_ids);
    lost_frames += d(s.lost_frames, last.lost_frames);
    last = s;
  }
  void firmware_restarted() { last = can::BmsRxStats{}; }
};

// What the firmware said in one tick (the last BMS_Status closes it).
struct Answer {
  EstimateRow row{};
  double theta[2] = {0, 0};
  bool have = false;
};

// Builds the frames of one tick from the measurement and the tick's faults.
class FaultyTransmitter {
 public:
  std::vector<hal::CanFrame> frames(std::size_t k, const can::Measurement& now, const can::Measurement& next,
                                    const hil::TickFaults& tf) {
    std::vector<hal::CanFrame> out;
    if (tf.unknown) {
      hal::CanFrame u{};
      u.id = 0x555;
      u.len = 8;
      for (int i = 0; i < 8; ++i) u.data[i] = static_cast<std::uint8_t>(0xA0 + i);
      out.push_back(u);
    }
    hal::CanFrame f{};
    if (pending_) {  // the earlier half of a swapped pair
      f = pending_frame_;
      pending_ = false;
    } else if (tf.reorder) {
      hal::CanFrame first{};
      encode(k, now, tf, first);
      encode(k + 1, next, hil::TickFaults{}, f);
      pending_frame_ = first;
      pending_ = true;
    } else {
      encode(k, now, tf, f);
    }
    if (tf.crc) f.data[4] ^= 0x10;  // after the CRC: the receiver must catch it
    const bool lost = tf.drop;
    if (tf.length) f.len = static_cast<std::uint8_t>(f.len - 1);
    if (!lost) {
      out.push_back(f);
      if (tf.dup) out.push_back(f);
    }
    if (lost || tf.length) {  // the clock still ticks (the firmware's timer would)
      can::Control c;
      c.lockstep = true;
      c.tick_trigger = true;
      c.tick = static_cast<std::uint32_t>(k);
      hal::CanFrame t{};
      tx_.encode(c, t);
      out.push_back(t);
    }
    return out;
  }

 private:
  void encode(std::size_t k, can::Measurement m, const hil::TickFaults& tf, hal::CanFrame& f) {
    m.seq = static_cast<std::uint16_t>(k & can::kSeqMask);
    if (tf.range) m.voltage_v = 7.0;
    if (tf.nan) (k % 2u == 0u ? m.voltage_v : m.current_a) = std::nan("");  // a failed ADC read of either channel
    if (tf.stale && have_frozen_) {
      can::encode(m, frozen_counter_, f);  // valid CRC, counter stuck
      return;
    }
    frozen_counter_ = tx_.next_counter(can::Msg::measurement);
    have_frozen_ = true;
    tx_.encode(m, f);
  }

  can::Transmitter tx_;
  hal::CanFrame pending_frame_{};
  bool pending_ = false;
  std::uint8_t frozen_counter_ = 0;
  bool have_frozen_ = false;
};

struct FaultCounts {
  std::size_t drop = 0, dup = 0, reorder = 0, crc = 0, length = 0, unknown = 0, stale = 0, range = 0, nan = 0,
              busdown = 0, kill = 0;
};

nlohmann::json fault_summary(const hil::FaultPlan& plan, const FaultCounts& inj, const RxTotals& rx,
                             const std::vector<EstimateRow>& rows, std::size_t no_answer, std::uint64_t stale_ticks,
                             int firmware_starts) {
  nlohmann::json w = nlohmann::json::array();
  for (const auto& win : plan.spec().windows) {
    // Recovered: the first answered tick after the window with no stale/range fault bit.
    const std::size_t end = win.start_tick + win.ticks;
    std::ptrdiff_t recover = -1;
    for (std::size_t k = end; k < rows.size(); ++k) {
      const std::uint32_t bad = kHostNoAnswer | can::fault_bit::kMeasStale | can::fault_bit::kVoltageRange |
                                can::fault_bit::kCurrentRange | can::fault_bit::kEstimator;
      if ((rows[k].status & bad) == 0u) {
        recover = static_cast<std::ptrdiff_t>(k - end);
        break;
      }
    }
    w.push_back({{"kind", hil::window_kind_name(win.kind)},
                 {"start", win.start_text},
                 {"start_tick", win.start_tick},
                 {"ticks", win.ticks},
                 {"recover_ticks_after_window", recover}});
  }
  return {{"spec", plan.spec().text},
          {"injected",
           {{"drop", inj.drop}, {"dup", inj.dup}, {"reorder", inj.reorder}, {"crc", inj.crc}, {"length", inj.length},
            {"unknown", inj.unknown}, {"stale", inj.stale}, {"range", inj.range}, {"nan", inj.nan},
            {"busdown_ticks", inj.busdown}, {"kill_ticks", inj.kill}}},
          {"firmware_counters",
           {{"dropped_length", rx.drop_length}, {"dropped_crc", rx.drop_crc}, {"dropped_counter", rx.drop_counter},
            {"ignored_ids", rx.ignored_ids}, {"lost_frames", rx.lost_frames}}},
          {"ticks_with_stale_fault", stale_ticks},
          {"ticks_without_answer", no_answer},
          {"firmware_starts", firmware_starts},
          {"windows", w}};
}

int run_hil(HilCli& c) {
  if (c.bus == "uml") exec_in_uml();
  if (c.realtime && !c.fault.empty()) throw InputError("--fault: lock-step only (drop it or --realtime)");
  const hil::FaultSpec spec = hil::parse_fault_spec(c.fault);
  // Checked before the long work: the output folder. Every file is written under DIR.partial
  // and moved into DIR only when the run succeeded (hil/staged_output.hpp).
  hil::StagedOutput out(c.out);
  if (!c.sim.quiet) std::fprintf(stderr, "hil: simulating the truth (%d cycles)...\n", c.sim.cycles);
  SimulateRun run = run_simulation(c.sim, {});
  // What goes on the bus: the measured values at the bus resolution (10 uV, 0.1 mA). The
  // truth.csv records exactly these, so `bmssim estimate` on it sees what the firmware saw.
  std::size_t n = run.result.samples.size();
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
  if (c.max_ticks > 0 && c.max_ticks < n) n = c.max_ticks;
  std::vector<fw::Mode> modes;
  for (std::size_t k = 0; k < n; ++k) modes.push_back(run.result.samples[k].mode);
  const hil::FaultPlan plan(spec, modes, c.sim.dt_s);  // bad windows: exit 2 before the bus is tried
  hal::lnx::SocketCanBus bus;
  if (bus.open(c.bus.c_str()) != hal::Status::ok)
    throw RuntimeFailure("cannot open CAN interface " + c.bus + ": " + bus.last_error() +
                         " (on a machine without kernel CAN use --bus uml)");
  const std::filesystem::path dir(c.out);
  write_truth_csv(out.path("truth.csv"), run.result, run.measured);

  const std::filesystem::path nvm = out.path("firmware.nvm");
  // The firmware's NVM here is a file, not flash: no write budget, so that --persist-every-s
  // is what the kill/restart test exercises.
  std::vector<std::string> fw_args = {"--can", c.bus, c.realtime ? "--realtime" : "--lockstep", "--nvm",
                                            nvm.string(), "--h", fmt::format("{}", c.h), "--persist-every-s",
                                            fmt::format("{}", c.persist_every_s), "--flash-endurance-cycles", "1e12"};
  if (c.beyond_paper) {
    fw_args.emplace_back("--beyond-paper");
  } else {
    fw_args.insert(fw_args.end(), {"--settings", c.settings});
  }
  hil::FirmwareProcess fw(c.firmware.empty() ? hil::default_firmware_path() : std::filesystem::path(c.firmware),
                          fw_args);

  CandumpWriter log(out.path("can.log"));
  const double t_epoch = 1700000000.0;  // fixed: lock-step logs are identical run to run
  FaultyTransmitter tx;
  can::Receiver rx(can::Node::host);
  can::LockstepTicks mirror;  // the firmware's trigger rule, to know how many answers to expect
  RxTotals rx_totals;
  FaultCounts inj;
  std::size_t no_answer = 0;
  std::uint64_t stale_ticks = 0, status_frames = 0, restored_answers = 0;
  double first_status_wall_s = -1, last_status_wall_s = -1;
  std::uint32_t first_tick_count = 0, last_tick_count = 0;
  EstimateResult res;
  res.rows.reserve(n);
  Answer last;
  const auto wall0 = std::chrono::steady_clock::now();
  auto wall_s = [&] { return std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count(); };

  // Reads frames until `expected` BMS_Status frames arrived (lock-step), or until `until_s`
  // of wall time (real time, expected ignored). Updates `last` with what arrived.
  auto collect = [&](std::size_t k, std::size_t expected, double t_log, double until_s) {
    std::size_t got = 0;
    while (c.realtime ? wall_s() < until_s : got < expected) {
      hal::CanFrame r{};
      const auto wait_ms = c.realtime ? std::max(1, static_cast<int>((until_s - wall_s()) * 1000.0)) : 2000;
      const hal::Status st = bus.receive(r, wait_ms);
      if (st == hal::Status::timeout) {
        if (c.realtime) continue;
        throw RuntimeFailure(fmt::format("the firmware did not answer tick {} within 2 s", k));
      }
      if (st != hal::Status::ok) throw RuntimeFailure(std::string("CAN receive failed: ") + bus.last_error());
      log.write(log_entry(c.realtime ? t_epoch + wall_s() : t_log, c.bus, r));
      can::RxMessage msg{};
      if (rx.accept(r, msg) != can::RxResult::accepted) continue;
      switch (msg.msg) {
        case can::Msg::estimate1:
          last.row.r_film_est_ohm_m2 = msg.estimate1.r_film_ohm_m2;
          last.row.mode = msg.estimate1.mode;
          last.row.rcsi_active = msg.estimate1.rcsi_active;
          break;
        case can::Msg::estimate2: last.theta[0] = msg.estimate2.theta0; break;
        case can::Msg::estimate3: last.theta[1] = msg.estimate3.theta1; break;
        case can::Msg::health:
          last.row.z_v = msg.health.z_v;
          last.row.li_loss_ah = msg.health.li_loss_ah;
          break;
        case can::Msg::rx_stats: rx_totals.add(msg.rx_stats); break;
        case can::Msg::status:
          last.row.status = msg.status.fault_bits;
          last.have = true;
          if ((msg.status.status_bits & can::status_bit::kNvmRestored) != 0u) ++restored_answers;
          if ((msg.status.fault_bits & can::fault_bit::kMeasStale) != 0u) ++stale_ticks;
          ++got;
          ++status_frames;
          last_status_wall_s = wall_s();
          last_tick_count = msg.status.tick_count;
          if (first_status_wall_s < 0) {
            first_status_wall_s = last_status_wall_s;
            first_tick_count = msg.status.tick_count;
          }
          break;
        default: break;
      }
    }
    return got;
  };

  for (std::size_t k = 0; k < n; ++k) {
    const auto& s = run.result.samples[k];
    const hil::TickFaults& tf = plan.at(k);
    if (tf.kill_now) fw.kill_hard();
    if (tf.restart_now) {
      fw.start();
      rx.reset();  // its alive counters start again at 0
      rx_totals.firmware_restarted();
    }
    if (tf.down_now) set_link(c.bus, "down");
    if (tf.up_now) set_link(c.bus, "up");
    can::Measurement now, next;
    now.voltage_v = run.measured.voltage_v[k];
    now.current_a = run.measured.current_a[k];
    if (k + 1 < n) {
      next.voltage_v = run.measured.voltage_v[k + 1];
      next.current_a = run.measured.current_a[k + 1];
    }
    inj.drop += tf.drop;
    inj.dup += tf.dup;
    inj.reorder += tf.reorder;
    inj.crc += tf.crc;
    inj.length += tf.length;
    inj.unknown += tf.unknown;
    inj.stale += tf.stale;
    inj.range += tf.range;
    inj.nan += tf.nan;
    inj.busdown += tf.bus_down;
    inj.kill += tf.fw_down;
    const auto frames = tx.frames(k, now, next, tf);
    if (c.realtime) {  // the firmware's timer ticks: answers are read while waiting for the next send time
      collect(k, 0, 0.0, 0.2 * static_cast<double>(k));
    }
    const double t_log = t_epoch + s.t_s;
    std::size_t triggers = 0;
    for (const auto& f : frames) {
      const hal::Status st = bus.send(f);
      if (st != hal::Status::ok) {
        if (tf.bus_down) continue;  // expected: ENETDOWN while the link is down
        throw RuntimeFailure(std::string("CAN send failed: ") + bus.last_error());
      }
      log.write(log_entry(c.realtime ? t_epoch + wall_s() : t_log, c.bus, f));
      std::uint32_t t = 0;
      if (mirror.classify(f, t)) ++triggers;
    }
    std::size_t answers = 0;
    if (!c.realtime && fw.running()) answers = collect(k, triggers, t_log, 0.0);
    EstimateRow row = last.row;
    // A tick whose frames were all repeats or late (duplicated, reordered) asks for nothing.
    const bool asked = triggers > 0 || tf.bus_down || !fw.running();
    if (!c.realtime && !asked) row.status |= kHostNotAsked;
    if (!c.realtime && asked && answers == 0) {
      row.status |= kHostNoAnswer;
      ++no_answer;
    }
    row.t_s = s.t_s;
    row.cycle = s.cycle;
    row.r_film_true_ohm_m2 = s.r_film_ohm_m2;
    if (!last.have) row.mode = s.mode;  // before the first answer
    row.model_voltage_v = std::nan("");
    row.model_current_a = std::nan("");
    row.j_side_a_m3 = std::nan("");
    res.rows.push_back(row);
    res.theta_rows.push_back({last.theta[0], last.theta[1]});
    if (!c.sim.quiet && k % 20000 == 0) std::fprintf(stderr, "hil: tick %zu / %zu\n", k, n);
  }
  if (c.realtime) collect(n, 0, 0.0, 0.2 * static_cast<double>(n));
  res.wall_s = wall_s();
  const int fw_exit = fw.stop();
  log.commit();
  res.theta = res.theta_rows.back();
  res.cycles = score_cycles(res.rows, true, modes);
  res.growth_err_pct = growth_error_pct(res.rows);
  write_estimates_csv(out.path("estimates.csv"), res);
  EstimateOptions eo;
  eo.h_v_per_ohm_m2 = c.h;
  eo.settings = c.beyond_paper ? "beyond-paper" : c.settings;
  auto summary = estimate_summary_json(res, eo);
  const double sim_s = run.result.samples[n - 1].t_s - run.result.samples[0].t_s + c.sim.dt_s;
  summary["simulation"] = summary_json(run.result);
  summary["simulation"]["options"] = options_json(c.sim);
  summary["simulation"]["parameters"] = run.parameters;
  summary["hil"] = {{"bus", c.bus},
                    {"lockstep", !c.realtime},
                    {"estimator", c.beyond_paper ? "beyond-paper" : c.settings},
                    {"ticks", n},
                    {"wall_s", res.wall_s},
                    {"sim_s", sim_s},
                    {"sim_s_per_wall_s", sim_s / res.wall_s},
                    {"firmware_exit", fw_exit},
                    {"frames_dropped_by_host", rx.counters().dropped_total()},
                    {"status_frames", status_frames},
                    {"answers_after_nvm_restore", restored_answers},
                    {"first_status_wall_s", first_status_wall_s},
                    {"last_status_wall_s", last_status_wall_s},
                    {"firmware_tick_count_first", first_tick_count},
                    {"firmware_tick_count_last", last_tick_count}};
  if (spec.any())
    summary["hil"]["faults"] = fault_summary(plan, inj, rx_totals, res.rows, no_answer, stale_ticks, fw.starts());
  else
    summary["hil"]["firmware_counters"] = {{"dropped_length", rx_totals.drop_length},
                                           {"dropped_crc", rx_totals.drop_crc},
                                           {"dropped_counter", rx_totals.drop_counter},
                                           {"ignored_ids", rx_totals.ignored_ids},
                                           {"lost_frames", rx_totals.lost_frames}};
  if (fw_exit != 0)
    throw RuntimeFailure(fmt::format("the firmware process exited with code {} (see its message above); nothing written to {}",
                                     fw_exit, dir.string()));
  write_file_atomically(out.path("summary.json"), summary.dump(2) + "\n");
  out.commit("summary.json");
  if (!c.sim.quiet) {
    std::fprintf(stderr, "hil: %zu ticks in %.2f s wall (%.0f x real time), firmware exit %d -> %s\n", n, res.wall_s,
                 sim_s / res.wall_s, fw_exit, dir.c_str());
    for (const auto& cs : res.cycles)
      std::fprintf(stderr, "hil: cycle %d: film-resistance error in CC charge: median %.3f %%, end %.3f %%\n",
                   cs.cycle, cs.r_film_err_median_pct, cs.r_film_err_end_pct);
  }
  return 0;
}

}  // namespace

Runner add_hil(CLI::App& app) {
  auto* sub = app.add_subcommand("hil", "Host-in-the-loop: the truth simulator feeds the firmware process over SocketCAN");
  auto c = std::make_shared<HilCli>();
  register_simulate_options(*sub, c->sim);
  sub->add_option("--bus", c->bus, "vcan0 (or any SocketCAN interface), or 'uml' to run inside a kernel with vcan")
      ->capture_default_str();
  sub->add_flag("--lockstep", c->lockstep, "Simulator-driven ticks, as fast as possible (default)");
  sub->add_flag("--realtime", c->realtime, "One measurement every 0.2 s of wall time; the firmware's timer ticks");
  sub->add_option("--h", c->h, "RCSI Markov parameter passed to the firmware")->capture_default_str();
  sub->add_option("--settings", c->settings,
                  "Estimator profile of the firmware: best (default) or paper, as `bmssim estimate --settings`")
      ->check(CLI::IsMember({"best", "paper"}))
      ->capture_default_str();
  sub->add_flag("--beyond-paper", c->beyond_paper,
                "Session 5's profile (as `bmssim estimate --beyond-paper`; --h is then not used)");
  sub->add_option("--firmware", c->firmware, "Path of bms-firmware (default: beside bmssim in the build tree)");
  sub->add_option("--persist-every-s", c->persist_every_s,
                  "Firmware commits its state to NVM every this many seconds of ticks (and at each CC-charge end)")
      ->capture_default_str()
      ->check(CLI::Range(0.0, 86400.0));
  sub->add_option("--max-ticks", c->max_ticks, "Stop after this many ticks (0: the whole profile; truth.csv keeps the whole profile)")
      ->capture_default_str();
  sub->add_option("--fault", c->fault,
                  "Bus faults, lock-step only: comma-separated KEY=VALUE.\n"
                  "Rates (probability per tick): drop=P dup=P reorder=P crc=P length=P unknown=P seed=K.\n"
                  "Windows START:TICKS, START = tick or MODE+SECONDS (e.g. cc_charge+600):\n"
                  "burst= (frames lost) stale= (alive counter frozen) range= (7 V) nan= (voltage NaN)\n"
                  "busdown= (ip link down/up) kill= (firmware SIGKILLed, restarted after TICKS).\n"
                  "Example: --fault drop=0.01,crc=0.01,kill=cc_charge+600:25,seed=3");
  sub->add_option("--out", c->out, "Output folder (truth.csv, estimates.csv, summary.json, can.log)")->required();
  return [c]() { return run_hil(*c); };
}

}  // namespace bms::app
