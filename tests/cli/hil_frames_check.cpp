// HIL == offline, bit for bit: the offline `bmssim estimate` on a HIL run's truth.csv,
// encoded through the firmware's own codec (bms/fw/can/can_protocol.hpp) with the firmware
// application's rules (seq = tick mod 4096, alive counter = frames sent mod 16, valid =
// finite film, theta as float32), must give the firmware's BMS_Estimate1/2/3 and BMS_Health
// frames of the run's can.log byte for byte, CRC included.
//
// The frames carry the film on a 1e-10 ohm m2 grid, so the run's estimates.csv (decoded
// frames) differs from the offline doubles by up to half a step (about 2e-8 relative at
// 3.7e-3 ohm m2): the check compares where the firmware's answer is exact, on the bus.
//
// usage: hil_frames_check HIL_DIR/can.log OFFLINE_DIR/estimates.csv
// Prints one PASS/FAIL line; exit 0 on PASS, 1 on FAIL, 2 on unreadable input.
#include <cmath>
#include <cstdio>
#include <cstring>
#include <exception>
#include <stdexcept>
#include <map>
#include <string>
#include <vector>

#include "bms/fw/can/can_protocol.hpp"
#include "io/candump_log.hpp"
#include "io/csv_table.hpp"

namespace can = bms::fw::can;

namespace {

struct Frame {
  std::uint32_t id = 0;
  std::uint8_t len = 0;
  std::uint8_t data[8]{};
};

can::Mode mode_of(const std::string& name) {
  for (can::Mode m : {can::Mode::rest, can::Mode::cc_discharge, can::Mode::cv_discharge, can::Mode::cc_charge,
                      can::Mode::cv_charge, can::Mode::unknown})
    if (name == can::mode_name(m)) return m;
  throw std::runtime_error("unknown mode '" + name + "' in estimates.csv");
}

// The five estimate frames the firmware sends for tick k, from the offline row k.
std::vector<Frame> offline_frames(const bms::CsvTable& t, std::size_t k) {
  const auto seq = static_cast<std::uint16_t>(k & can::kSeqMask);
  const auto counter = static_cast<std::uint8_t>(k & can::kCounterMask);
  can::Estimate1 e1;
  e1.seq = seq;
  e1.r_film_ohm_m2 = t.numbers("r_film_est_ohm_m2")[k];
  e1.mode = mode_of(t.strings("mode")[k]);
  e1.rcsi_active = t.numbers("rcsi_active")[k] != 0.0;
  e1.valid = std::isfinite(e1.r_film_ohm_m2);
  can::Estimate2 e2{seq, static_cast<float>(t.numbers("theta_m1")[k])};
  can::Estimate3 e3{seq, static_cast<float>(t.numbers("theta_n1")[k])};
  can::Health h{seq, t.numbers("li_loss_ah")[k], t.numbers("z_v")[k]};
  can::Uncertainty u{seq, can::below_none(t.numbers("r_film_sd_ohm_m2")[k], can::sig::kRFilmSd),
                     can::below_none(t.numbers("capacity_est_ah")[k], can::sig::kCapacity),
                     can::below_none(t.numbers("capacity_sd_ah")[k], can::sig::kCapacitySd)};
  std::vector<Frame> out(5);
  can::encode(e1, counter, out[0]);
  can::encode(e2, counter, out[1]);
  can::encode(e3, counter, out[2]);
  can::encode(h, counter, out[3]);
  can::encode(u, counter, out[4]);
  return out;
}

int run(const char* log_path, const char* csv_path) {
  const auto log = bms::read_candump_log(log_path);
  const bms::CsvTable t = bms::read_csv(csv_path, {"mode"});
  std::map<std::uint32_t, std::vector<const bms::CanLogEntry*>> by_id;
  for (const auto& e : log) by_id[e.id].push_back(&e);
  const std::uint32_t ids[5] = {can::id::kEstimate1, can::id::kEstimate2, can::id::kEstimate3, can::id::kHealth,
                                can::id::kUncertainty};
  std::size_t mismatches = 0, compared = 0, first_bad = SIZE_MAX;
  bool counts_ok = true;
  for (std::uint32_t id : ids) counts_ok &= by_id[id].size() == t.rows();
  for (std::size_t k = 0; counts_ok && k < t.rows(); ++k) {
    const auto want = offline_frames(t, k);
    bool same = true;
    for (int i = 0; i < 5; ++i) {
      const bms::CanLogEntry& got = *by_id[ids[i]][k];
      const Frame& w = want[static_cast<std::size_t>(i)];
      const bool equal = got.dlc == w.len && std::memcmp(got.data.data(), w.data, got.dlc) == 0;
      if (!equal && mismatches < 5) {
        std::fprintf(stderr, "tick %zu id %03X: firmware", k, static_cast<unsigned>(got.id));
        for (int b = 0; b < got.dlc; ++b) std::fprintf(stderr, " %02X", got.data[static_cast<std::size_t>(b)]);
        std::fprintf(stderr, ", offline");
        for (int b = 0; b < w.len; ++b) std::fprintf(stderr, " %02X", w.data[b]);
        std::fprintf(stderr, "\n");
      }
      same &= equal;
      ++compared;
    }
    if (!same && first_bad == SIZE_MAX) first_bad = k;
    mismatches += same ? 0u : 1u;
  }
  const bool pass = counts_ok && mismatches == 0;
  std::printf("%s offline `bmssim estimate` encoded with the firmware's codec equals the firmware's estimate frames "
              "bit for bit: %zu ticks, %zu frames (BMS_Estimate1/2/3, BMS_Health, BMS_Uncertainty, CRC included), %zu mismatched "
              "ticks%s\n",
              pass ? "PASS" : "FAIL", t.rows(), compared, mismatches,
              !counts_ok ? " (frame counts differ from the offline rows)"
              : first_bad != SIZE_MAX ? (", first at tick " + std::to_string(first_bad)).c_str()
                                      : "");
  return pass ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 3) {
    std::fprintf(stderr, "usage: hil_frames_check HIL_DIR/can.log OFFLINE_DIR/estimates.csv\n");
    return 2;
  }
  try {
    return run(argv[1], argv[2]);
  } catch (const std::exception& e) {
    std::fprintf(stderr, "hil_frames_check: %s\n", e.what());
    return 2;
  }
}
