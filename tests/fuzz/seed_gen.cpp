// Writes the binary seed inputs of tests/fuzz/corpus/{can_receiver,nvm_record}/ with the
// firmware's own encoders, so that the fuzzer starts from frames with good CRCs and
// counters and from valid NVM records instead of having to find them.
//   build/fuzz/fuzz_seed_gen tests/fuzz/corpus
// The text seeds (expressions, BPX, CSV, candump) are written by hand.
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <string>
#include <vector>

#include "bms/fw/can/can_protocol.hpp"
#include "bms/fw/nvm/nvm_store.hpp"
#include "bms/fw/estimation/rcsi_estimator.hpp"
#include "../common/rcsi_test_config.hpp"

namespace can = bms::fw::can;
namespace nvm = bms::fw::nvm;

namespace {

using Bytes = std::vector<std::uint8_t>;

struct Frame {
  std::uint32_t id;
  std::uint8_t len;
  std::uint8_t data[8];
};

bool write_file(const std::string& path, const Bytes& b) {
  std::FILE* f = std::fopen(path.c_str(), "wb");
  if (f == nullptr) return false;
  const bool ok = std::fwrite(b.data(), 1, b.size(), f) == b.size();
  return std::fclose(f) == 0 && ok;
}

// One record of fuzz_can_receiver's input: flags, id lo, id hi, len, 8 data bytes.
void add(Bytes& out, const Frame& f, std::uint8_t flags) {
  out.push_back(flags);
  out.push_back(static_cast<std::uint8_t>(f.id & 0xFFu));
  out.push_back(static_cast<std::uint8_t>((f.id >> 8u) & 0xFFu));
  out.push_back(f.len);
  out.insert(out.end(), f.data, f.data + 8);
}

template <class M>
Frame encoded(const M& m, std::uint8_t counter) {
  Frame f{};
  can::encode(m, counter, f);
  return f;
}

using Estimator = bms::fw::RcsiEstimator<double, 2, 1>;

Estimator::State some_state(int ticks) {
  Estimator est(bms::test::rcsi_test_config<Estimator>());
  for (int k = 0; k < ticks; ++k) {
    est.predict();
    est.update(1e-5 * (k % 7 - 3), -10.0 + 0.1 * (k % 5));
  }
  return est.save();
}

Bytes record(const Estimator::State& s, std::uint32_t seq) {
  Bytes r(nvm::record_bytes(sizeof s));
  nvm::encode_record(&s, sizeof s, Estimator::kLayoutTag, seq, r.data(), r.size());
  return r;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s CORPUS_DIR (holding can_receiver/ and nvm_record/)\n", argv[0]);
    return 2;
  }
  const std::string dir = argv[1];
  bool ok = true;

  // BMS side: measurements with counters and ticks, a control frame, a temperature, then
  // the faults the receiver must count: bad CRC, frozen counter, wrong length, unknown id.
  {
    Bytes in{0};
    can::Transmitter tx;
    for (std::uint16_t k = 0; k < 4; ++k) {
      can::Measurement m;
      m.seq = k;
      m.voltage_v = 3.3 + 0.01 * k;
      m.current_a = -2.0;
      Frame f{};
      tx.encode(m, f);
      add(in, f, 1);
    }
    can::Control ctl;
    ctl.lockstep = true;
    ctl.tick_trigger = true;
    ctl.tick = 4;
    Frame f{};
    tx.encode(ctl, f);
    add(in, f, 0);
    can::Temperature t;
    t.temperature_k = 298.15;
    tx.encode(t, f);
    add(in, f, 0);
    Frame bad = encoded(can::Measurement{}, 5);
    bad.data[0] ^= 0x5Au;
    add(in, bad, 1);
    add(in, encoded(can::Measurement{}, 4), 1);  // counter repeated
    Frame short_frame = encoded(can::Measurement{}, 6);
    short_frame.len = 7;
    add(in, short_frame, 1);
    Frame unknown{};
    unknown.id = 0x7FF;
    unknown.len = 8;
    add(in, unknown, 4);  // also drives the physical encoders
    ok = write_file(dir + "/can_receiver/bms_stream.bin", in) && ok;
  }
  // Host side: everything the BMS sends.
  {
    Bytes in{1};
    can::Transmitter tx;
    Frame f{};
    can::Estimate1 e1;
    e1.seq = 17;
    e1.r_film_ohm_m2 = bms::fw::paper::kInitialFilm_ohm_m2;
    e1.mode = bms::fw::Mode::cc_charge;
    e1.valid = true;
    tx.encode(e1, f);
    add(in, f, 0);
    can::Estimate2 e2;
    e2.seq = 17;
    e2.theta0 = 1.0f;
    tx.encode(e2, f);
    add(in, f, 0);
    can::Estimate3 e3;
    e3.seq = 17;
    e3.theta1 = -2.3712e-10f;
    tx.encode(e3, f);
    add(in, f, 0);
    can::Health h;
    h.seq = 17;
    h.li_loss_ah = 0.012;
    h.z_v = -3e-4;
    tx.encode(h, f);
    add(in, f, 0);
    can::Uncertainty u;
    u.seq = 17;
    u.r_film_sd_ohm_m2 = 5e-5;
    u.capacity_ah = 2.3;
    u.capacity_sd_ah = 0.0012;
    tx.encode(u, f);
    add(in, f, 0);
    can::BmsStatus st;
    st.status_bits = can::status_bit::kRunning;
    st.tick_count = 17;
    tx.encode(st, f);
    add(in, f, 1);
    can::BmsRxStats rs;
    rs.drop_crc = 2;
    tx.encode(rs, f);
    add(in, f, 1);
    ok = write_file(dir + "/can_receiver/host_stream.bin", in) && ok;
  }

  // NVM: a valid record (modes 0 and 1), a torn one, and two-slot images (mode 2).
  const Estimator::State s1 = some_state(10);
  const Estimator::State s2 = some_state(11);
  {
    Bytes in{0};
    const Bytes r = record(s1, 5);
    in.insert(in.end(), r.begin(), r.end());
    ok = write_file(dir + "/nvm_record/valid_record.bin", in) && ok;
    in[0] = 1;
    ok = write_file(dir + "/nvm_record/valid_record_fixcrc.bin", in) && ok;
    Bytes torn{0};
    torn.insert(torn.end(), r.begin(), r.begin() + 150);
    torn.resize(1 + r.size(), 0xFF);
    ok = write_file(dir + "/nvm_record/torn_record.bin", torn) && ok;
  }
  {
    constexpr std::size_t kStride = 320;  // fuzz_nvm_record's device: 296-byte record, 32-byte pages
    Bytes image(1 + 2 * kStride, 0xFF);
    image[0] = 2;
    const Bytes a = record(s1, 0xFFFFFFFFu);
    const Bytes b = record(s2, 0u);  // newer, across the wrap
    std::memcpy(image.data() + 1, a.data(), a.size());
    std::memcpy(image.data() + 1 + kStride, b.data(), b.size());
    ok = write_file(dir + "/nvm_record/two_slots_wrap.bin", image) && ok;
    std::memset(image.data() + 1 + kStride + 200, 0xFF, 96);  // slot 1 torn after 200 bytes
    ok = write_file(dir + "/nvm_record/two_slots_one_torn.bin", image) && ok;
  }
  if (!ok) {
    std::fprintf(stderr, "fuzz_seed_gen: cannot write into %s\n", dir.c_str());
    return 1;
  }
  return 0;
}
