// bmssim hil: the truth simulator feeds the firmware process (bms-firmware) over SocketCAN.
// Lock-step: the simulator owns the clock; the frames of one tick are sent, and the host
// waits for one BMS_Status per tick trigger among them (deterministic, as fast as the bus
// allows). Real time: one measurement every 0.2 s of wall time; the firmware's own timer
// ticks. --fault injects bus faults into the measurement stream (host_sim/src/hil/fault_plan.hpp).
// --bus uml re-runs this command inside a Linux kernel with vcan (scripts/vcan-run.sh).
#include <unistd.h>

#include <chrono>
#include <cstdlib>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <thread>
#include <vector>

#include <fmt/format.h>

#include "bms/fw/can/can_protocol.hpp"
#include "bms/hal/linux/socketcan.hpp"
#include "estimation/estimate_output.hpp"
#include "estimation/estimate_run.hpp"
#include "hil/fault_plan.hpp"
#include "hil/hil_session.hpp"
#include "hil/firmware_process.hpp"
#include "io/atomic_file.hpp"
#include "io/candump_log.hpp"
#include "io/child_process.hpp"
#include "io/input_error.hpp"
#include "io/output_folder.hpp"
#include "sim/truth_output.hpp"

namespace bms::hil {

namespace {

namespace can = fw::can;

// estimates.csv status column: bits 0..7 are the firmware's FaultBits; this host bit marks
// a tick the firmware did not answer (killed, or the bus down): the row holds the last answer.
constexpr std::uint32_t kHostNoAnswer = 1u << 8;
// ... and this one a tick whose frames were all repeats or late (duplicated, reordered), so
// they triggered no firmware tick: nothing was asked, the row holds the last answer.
constexpr std::uint32_t kHostNotAsked = 1u << 9;


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
// This process waits for it: the guest writes into the staging folder of the caller's OutputFolder (named by this
// process's id, io/output_folder.hpp), so a run stopped by a signal, or a guest that died,
// leaves nothing: the caller's OutputFolder removes it unless the guest committed it. Returns the exit
// code of the run inside; Interrupted when a signal stopped it (forwarded to the runner,
// which stops the guest).
int run_in_uml() {
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
  setenv(kOutputOwnerVariable, std::to_string(output_folder_owner()).c_str(), 1);
  int rc = 0;
  try {
    rc = run_process(args);
  } catch (...) {
    unsetenv(kOutputOwnerVariable);
    throw;
  }
  unsetenv(kOutputOwnerVariable);
  throw_if_interrupted();
  return rc;
}

// `ip link set IFACE up|down` (the bus going away and coming back).
void set_link(const std::string& iface, const char* state) {
  SpawnOptions o;
  o.search_path = true;
  if (run_process({"ip", "link", "set", iface, state}, o) != 0)
    throw RuntimeFailure("ip link set " + iface + " " + state + " failed");
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

void count_faults(const hil::TickFaults& tf, FaultCounts& inj) {
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
}

// The truth run, with its measured columns put on the bus's grid (10 uV, 0.1 mA) through
// the codec: truth.csv records exactly these, so `bmssim estimate` on it sees what the
// firmware saw.
SimulateRun simulate_on_bus_grid(const SimulateOptions& sim) {
  if (!sim.quiet) std::fprintf(stderr, "hil: simulating the truth (%d cycles)...\n", sim.cycles);
  SimulateRun run = run_simulation(sim, {});
  for (std::size_t i = 0; i < run.result.samples.size(); ++i) {
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
  return run;
}

std::vector<std::string> firmware_args(const HilConfig& c, const std::filesystem::path& nvm) {
  // The firmware's NVM here is a file, not flash: no write budget, so that --persist-every-s
  // is what the kill/restart test exercises.
  std::vector<std::string> a = {"--can", c.bus, c.realtime ? "--realtime" : "--lockstep", "--nvm", nvm.string(),
                                "--persist-every-s", fmt::format("{}", c.persist_every_s), "--flash-endurance-cycles",
                                "1e12", "--settings", fw::profile_name(c.profile)};
  if (c.overrides.h_v_per_ohm_m2.given) a.insert(a.end(), {"--h", fmt::format("{}", c.overrides.h_v_per_ohm_m2.value)});
  return a;
}

// One host-in-the-loop run: the bus, the firmware process, what was sent and answered.
class HilSession {
 public:
  HilSession(const HilConfig& c, SimulateRun run, std::size_t n, std::vector<fw::Mode> modes, const hil::FaultPlan& plan,
             OutputFolder& out)
      : c_(c), run_(std::move(run)), n_(n), modes_(std::move(modes)), plan_(plan), out_(out) {}

  void open_bus() {
    if (bus_.open(c_.bus.c_str()) != hal::Status::ok)
      throw RuntimeFailure("cannot open CAN interface " + c_.bus + ": " + bus_.last_error() +
                           " (on a machine without kernel CAN use --bus uml)");
  }

  void run() {
    write_truth_csv(out_.staging() / "truth.csv", run_.result, run_.measured);
    fw_ = std::make_unique<hil::FirmwareProcess>(
        c_.firmware.empty() ? hil::default_firmware_path() : std::filesystem::path(c_.firmware),
        firmware_args(c_, out_.staging() / "firmware.nvm"));
    log_ = std::make_unique<CandumpWriter>(out_.staging() / "can.log");
    res_.rows.reserve(n_);
    wall0_ = std::chrono::steady_clock::now();
    for (std::size_t k = 0; k < n_; ++k) run_tick(k);
    if (c_.realtime) collect(n_, 0, 0.0, 0.2 * static_cast<double>(n_));
    res_.wall_s = wall_s();
    fw_exit_ = fw_->stop();
    log_->commit();
  }

  void write_outputs(const hil::FaultSpec& spec);

 private:
  double wall_s() const {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0_).count();
  }
  void apply_process_and_link_faults(const hil::TickFaults& tf);
  void run_tick(std::size_t k);
  std::size_t send_tick(const std::vector<hal::CanFrame>& frames, const hil::TickFaults& tf, double t_log);
  void record_row(std::size_t k, std::size_t triggers, std::size_t answers, const hil::TickFaults& tf);
  std::size_t collect(std::size_t k, std::size_t expected, double t_log, double until_s);
  bool take(const can::RxMessage& msg);
  nlohmann::json hil_json(const hil::FaultSpec& spec, double sim_s) const;

  const HilConfig& c_;
  SimulateRun run_;
  std::size_t n_;
  std::vector<fw::Mode> modes_;
  const hil::FaultPlan& plan_;
  OutputFolder& out_;
  hal::lnx::SocketCanBus bus_;
  std::unique_ptr<hil::FirmwareProcess> fw_;
  std::unique_ptr<CandumpWriter> log_;
  int fw_exit_ = 0;
  static constexpr double kEpochS = 1700000000.0;  // fixed: lock-step logs are identical run to run
  FaultyTransmitter tx_;
  can::Receiver rx_{can::Node::host};
  can::LockstepTicks mirror_;  // the firmware's trigger rule, to know how many answers to expect
  RxTotals rx_totals_;
  FaultCounts inj_;
  std::size_t no_answer_ = 0;
  std::uint64_t stale_ticks_ = 0, status_frames_ = 0, restored_answers_ = 0;
  double first_status_wall_s_ = -1, last_status_wall_s_ = -1;
  std::uint32_t first_tick_count_ = 0, last_tick_count_ = 0;
  EstimateResult res_;
  Answer last_;
  std::chrono::steady_clock::time_point wall0_;
};

void HilSession::apply_process_and_link_faults(const hil::TickFaults& tf) {
  if (tf.kill_now) fw_->kill_hard();
  if (tf.restart_now) {
    fw_->start();
    rx_.reset();  // its alive counters start again at 0
    rx_totals_.firmware_restarted();
  }
  if (tf.down_now) set_link(c_.bus, "down");
  if (tf.up_now) set_link(c_.bus, "up");
}

void HilSession::run_tick(std::size_t k) {
  throw_if_interrupted();  // SIGINT/SIGTERM reached the firmware too (io/child_process)
  const hil::TickFaults& tf = plan_.at(k);
  apply_process_and_link_faults(tf);
  can::Measurement now, next;
  now.voltage_v = run_.measured.voltage_v[k];
  now.current_a = run_.measured.current_a[k];
  if (k + 1 < n_) {
    next.voltage_v = run_.measured.voltage_v[k + 1];
    next.current_a = run_.measured.current_a[k + 1];
  }
  count_faults(tf, inj_);
  const auto frames = tx_.frames(k, now, next, tf);
  // Real time: the firmware's timer ticks; answers are read while waiting for the send time.
  if (c_.realtime) collect(k, 0, 0.0, 0.2 * static_cast<double>(k));
  const double t_log = kEpochS + run_.result.samples[k].t_s;
  const std::size_t triggers = send_tick(frames, tf, t_log);
  std::size_t answers = 0;
  if (!c_.realtime && fw_->running()) answers = collect(k, triggers, t_log, 0.0);
  record_row(k, triggers, answers, tf);
  if (!c_.sim.quiet && k % 20000 == 0) std::fprintf(stderr, "hil: tick %zu / %zu\n", k, n_);
}

// Sends one tick's frames; returns how many of them trigger a firmware tick.
std::size_t HilSession::send_tick(const std::vector<hal::CanFrame>& frames, const hil::TickFaults& tf, double t_log) {
  std::size_t triggers = 0;
  for (const auto& f : frames) {
    const hal::Status st = bus_.send(f);
    if (st != hal::Status::ok) {
      if (tf.bus_down) continue;  // expected: ENETDOWN while the link is down
      throw RuntimeFailure(std::string("CAN send failed: ") + bus_.last_error());
    }
    log_->write(log_entry(c_.realtime ? kEpochS + wall_s() : t_log, c_.bus, f));
    std::uint32_t t = 0;
    if (mirror_.classify(f, t)) ++triggers;
  }
  return triggers;
}

void HilSession::record_row(std::size_t k, std::size_t triggers, std::size_t answers, const hil::TickFaults& tf) {
  const auto& s = run_.result.samples[k];
  EstimateRow row = last_.row;
  // A tick whose frames were all repeats or late (duplicated, reordered) asks for nothing.
  const bool asked = triggers > 0 || tf.bus_down || !fw_->running();
  if (!c_.realtime && !asked) row.status |= kHostNotAsked;
  if (!c_.realtime && asked && answers == 0) {
    row.status |= kHostNoAnswer;
    ++no_answer_;
  }
  row.t_s = s.t_s;
  row.cycle = s.cycle;
  row.r_film_true_ohm_m2 = s.r_film_ohm_m2;
  row.capacity_true_ah = s.capacity_ah;
  if (!last_.have) {  // before the first answer
    row.mode = s.mode;
    row.r_film_sd_ohm_m2 = row.capacity_est_ah = row.capacity_sd_ah = std::nan("");
  }
  row.model_voltage_v = std::nan("");
  row.model_current_a = std::nan("");
  row.j_side_a_m3 = std::nan("");
  row.innovation_test_ratio = std::nan("");  // not on the bus
  res_.rows.push_back(row);
  res_.theta_rows.push_back({last_.theta[0], last_.theta[1]});
}

// Reads frames until `expected` BMS_Status frames arrived (lock-step), or until `until_s`
// of wall time (real time, expected ignored). Updates last_ with what arrived.
std::size_t HilSession::collect(std::size_t k, std::size_t expected, double t_log, double until_s) {
  std::size_t got = 0;
  while (c_.realtime ? wall_s() < until_s : got < expected) {
    hal::CanFrame r{};
    const auto wait_ms = c_.realtime ? std::max(1, static_cast<int>((until_s - wall_s()) * 1000.0)) : 2000;
    const hal::Status st = bus_.receive(r, wait_ms);
    if (st == hal::Status::timeout) {
      if (c_.realtime) continue;
      throw_if_interrupted();
      throw RuntimeFailure(fmt::format("the firmware did not answer tick {} within 2 s", k));
    }
    if (st != hal::Status::ok) throw RuntimeFailure(std::string("CAN receive failed: ") + bus_.last_error());
    log_->write(log_entry(c_.realtime ? kEpochS + wall_s() : t_log, c_.bus, r));
    can::RxMessage msg{};
    if (rx_.accept(r, msg) == can::RxResult::accepted && take(msg)) ++got;
  }
  return got;
}

// BMS_Uncertainty's largest raw value means none (the firmware sends real values under it).
double none_at_top(double si, const can::SignalLayout& s) {
  return si >= s.max / s.units_per_si ? std::nan("") : si;
}

// Takes one accepted answer into last_; true for the BMS_Status that closes a tick.
bool HilSession::take(const can::RxMessage& msg) {
  switch (msg.msg) {
    case can::Msg::estimate1:
      last_.row.r_film_est_ohm_m2 = msg.estimate1.r_film_ohm_m2;
      last_.row.mode = msg.estimate1.mode;
      last_.row.rcsi_active = msg.estimate1.rcsi_active;
      return false;
    case can::Msg::estimate2: last_.theta[0] = msg.estimate2.theta0; return false;
    case can::Msg::estimate3: last_.theta[1] = msg.estimate3.theta1; return false;
    case can::Msg::health:
      last_.row.z_v = msg.health.z_v;
      last_.row.li_loss_ah = msg.health.li_loss_ah;
      return false;
    case can::Msg::uncertainty:
      last_.row.r_film_sd_ohm_m2 = none_at_top(msg.uncertainty.r_film_sd_ohm_m2, can::sig::kRFilmSd);
      last_.row.capacity_est_ah = none_at_top(msg.uncertainty.capacity_ah, can::sig::kCapacity);
      last_.row.capacity_sd_ah = none_at_top(msg.uncertainty.capacity_sd_ah, can::sig::kCapacitySd);
      return false;
    case can::Msg::rx_stats: rx_totals_.add(msg.rx_stats); return false;
    case can::Msg::status: break;
    default: return false;
  }
  last_.row.status = msg.status.fault_bits;
  last_.have = true;
  if ((msg.status.status_bits & can::status_bit::kNvmRestored) != 0u) ++restored_answers_;
  if ((msg.status.fault_bits & can::fault_bit::kMeasStale) != 0u) ++stale_ticks_;
  ++status_frames_;
  last_status_wall_s_ = wall_s();
  last_tick_count_ = msg.status.tick_count;
  if (first_status_wall_s_ < 0) {
    first_status_wall_s_ = last_status_wall_s_;
    first_tick_count_ = msg.status.tick_count;
  }
  return true;
}

nlohmann::json HilSession::hil_json(const hil::FaultSpec& spec, double sim_s) const {
  nlohmann::json h = {{"bus", c_.bus},
                      {"lockstep", !c_.realtime},
                      {"estimator", fw::profile_name(c_.profile)},
                      {"ticks", n_},
                      {"wall_s", res_.wall_s},
                      {"sim_s", sim_s},
                      {"sim_s_per_wall_s", sim_s / res_.wall_s},
                      {"firmware_exit", fw_exit_},
                      {"frames_dropped_by_host", rx_.counters().dropped_total()},
                      {"status_frames", status_frames_},
                      {"answers_after_nvm_restore", restored_answers_},
                      {"first_status_wall_s", first_status_wall_s_},
                      {"last_status_wall_s", last_status_wall_s_},
                      {"firmware_tick_count_first", first_tick_count_},
                      {"firmware_tick_count_last", last_tick_count_}};
  if (spec.any())
    h["faults"] = fault_summary(plan_, inj_, rx_totals_, res_.rows, no_answer_, stale_ticks_, fw_->starts());
  else
    h["firmware_counters"] = {{"dropped_length", rx_totals_.drop_length}, {"dropped_crc", rx_totals_.drop_crc},
                              {"dropped_counter", rx_totals_.drop_counter}, {"ignored_ids", rx_totals_.ignored_ids},
                              {"lost_frames", rx_totals_.lost_frames}};
  return h;
}

void HilSession::write_outputs(const hil::FaultSpec& spec) {
  res_.theta = res_.theta_rows.back();
  res_.cycles = score_cycles(res_.rows, true, modes_);
  res_.growth_err_pct = growth_error_pct(res_.rows);
  write_estimates_csv(out_.staging() / "estimates.csv", res_);
  EstimateOptions eo;
  eo.profile = c_.profile;
  eo.overrides = c_.overrides;
  // The firmware's configuration (the same make_config call bms-firmware makes).
  using FirmwareCore = fw::BmsCore<double>;
  FirmwareCore::Config firmware_config{};
  (void)fw::make_config<FirmwareCore>(fw::paper_nominal_cell<double>(), c_.profile, c_.overrides, firmware_config);
  res_.config = summarise_config(firmware_config, 1);
  auto summary = estimate_summary_json(res_, eo);
  const auto& samples = run_.result.samples;
  const double sim_s = samples[n_ - 1].t_s - samples[0].t_s + c_.sim.dt_s;
  summary["simulation"] = summary_json(run_.result);
  summary["simulation"]["options"] = options_json(c_.sim);
  summary["simulation"]["parameters"] = run_.parameters;
  summary["hil"] = hil_json(spec, sim_s);
  if (fw_exit_ != 0)
    throw RuntimeFailure(fmt::format("the firmware process exited with code {} (see its message above); nothing written to {}",
                                     fw_exit_, c_.out));
  write_file_atomically(out_.staging() / "summary.json", summary.dump(2) + "\n");
  out_.commit();
  if (c_.sim.quiet) return;
  std::fprintf(stderr, "hil: %zu ticks in %.2f s wall (%.0f x real time), firmware exit %d -> %s\n", n_, res_.wall_s,
               sim_s / res_.wall_s, fw_exit_, c_.out.c_str());
  for (const auto& cs : res_.cycles)
    std::fprintf(stderr, "hil: cycle %d: film-resistance error in CC charge: median %.3f %%, end %.3f %%\n", cs.cycle,
                 cs.r_film_err_median_pct, cs.r_film_err_end_pct);
}

}  // namespace

int run_hil(const HilConfig& c) {
  // The options first, before a kernel is booted for --bus uml.
  if (c.realtime && !c.fault.empty()) throw InputError("--fault: lock-step only (drop it or --realtime)");
  const hil::FaultSpec spec = hil::parse_fault_spec(c.fault);
  // Checked before the long work (and before a kernel boots): the output folder. Every file is
  // written under DIR.partial-PID that replaces DIR whole only when the run succeeded
  // (io/output_folder.hpp).
  OutputFolder out(c.out);
  if (c.bus == "uml") return run_in_uml();  // `out` is committed inside, or removed here
  SimulateRun run = simulate_on_bus_grid(c.sim);
  std::size_t n = run.result.samples.size();
  if (c.max_ticks > 0 && c.max_ticks < n) n = c.max_ticks;
  std::vector<fw::Mode> modes;
  for (std::size_t k = 0; k < n; ++k) modes.push_back(run.result.samples[k].mode);
  const hil::FaultPlan plan(spec, modes, c.sim.dt_s);  // bad windows: exit 2 before the bus is tried
  HilSession session(c, std::move(run), n, modes, plan, out);
  session.open_bus();
  session.run();
  session.write_outputs(spec);
  return 0;
}

}  // namespace bms::hil
