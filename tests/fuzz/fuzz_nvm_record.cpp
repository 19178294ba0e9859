// Fuzz target: the NVM record decoder and the two-slot store's load
// (firmware/include/bms/fw/nvm/nvm_store.hpp), fed with whatever a worn, torn or tampered flash
// can hold, and the estimator's restore() of any record that passes.
//
// Input: byte 0 picks the mode, the rest is the data.
//   mode 0: check_record() on the raw bytes.
//   mode 1: the same after writing the correct CRC into the bytes (where the stored length
//           says it is), so the fields behind the CRC (version, tag, length, payload) are
//           reached without the fuzzer having to solve a CRC-32.
//   mode 2: the bytes become the NVM image of both slots (CRCs fixed as in mode 1 when
//           bit 7 of byte 0 is set), then load(); load must return the newest valid slot
//           as an independent decode of each slot says; then save() and load() again.
// Whenever a record is accepted, its payload goes to RcsiEstimator::restore(): an accepted
// image must leave an estimator whose next tick is finite.
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <vector>

#include "bms/fw/nvm/nvm_store.hpp"
#include "bms/fw/estimation/rcsi_estimator.hpp"
#include "../common/rcsi_test_config.hpp"

namespace nvm = bms::fw::nvm;

namespace {

using Estimator = bms::fw::RcsiEstimator<double, 2, 1>;
using State = Estimator::State;
constexpr std::uint32_t kTag = Estimator::kLayoutTag;
constexpr std::size_t kPage = 32;

[[noreturn]] void fail() { std::abort(); }

// A RAM device with the HAL's NVM member functions (duck-typed for the store).
enum class Status : std::uint8_t { ok = 0, out_of_range, invalid_argument };
struct MemNvm {
  std::array<std::uint8_t, 1024> mem{};
  std::size_t size_bytes() const { return mem.size(); }
  std::size_t page_size() const { return kPage; }
  Status read(std::size_t o, void* d, std::size_t n) {
    if (o > mem.size() || n > mem.size() - o) return Status::out_of_range;
    std::memcpy(d, mem.data() + o, n);
    return Status::ok;
  }
  Status write(std::size_t o, const void* s, std::size_t n) {
    if (o > mem.size() || n > mem.size() - o) return Status::out_of_range;
    std::memcpy(mem.data() + o, s, n);
    return Status::ok;
  }
  Status erase(std::size_t o, std::size_t n) {
    if (o % kPage != 0 || n % kPage != 0) return Status::invalid_argument;
    if (o > mem.size() || n > mem.size() - o) return Status::out_of_range;
    std::memset(mem.data() + o, 0xFF, n);
    return Status::ok;
  }
};
using Store = nvm::RecordStore<State, kTag, MemNvm>;

Estimator::Config config() { return bms::test::rcsi_test_config<Estimator>(); }

// Restoring an accepted record must give a usable estimator, or be refused.
void restore_and_tick(const std::uint8_t* payload) {
  State s;
  std::memcpy(&s, payload, sizeof s);
  Estimator est(config());
  if (!est.restore(s)) return;
  const double u_hat = est.predict();
  if (!std::isfinite(u_hat)) fail();
  est.update(1e-4, -10.0);
  if (!est.theta().allFinite() || !est.p().allFinite()) fail();
}

// Write the CRC a record at `p` (n bytes) would need, at the offset its length field names.
void fix_crc(std::uint8_t* p, std::size_t n) {
  if (n < nvm::kRecordOverheadBytes) return;
  const std::uint32_t len = nvm::detail::get_u32(p + 16);
  if (len > n - nvm::kRecordOverheadBytes) return;
  const std::size_t at = nvm::kRecordHeaderBytes + len;
  nvm::detail::put_u32(p + at, nvm::crc32(p, at));
}

void decode(const std::uint8_t* p, std::size_t n) {
  nvm::RecordView view;
  const nvm::RecordCheck c = nvm::check_record(p, n, kTag, sizeof(State), view);
  (void)nvm::record_check_name(c);
  if (c != nvm::RecordCheck::valid) return;
  if (view.payload_bytes != sizeof(State) || view.payload < p || view.payload + view.payload_bytes > p + n) fail();
  // An accepted record re-encodes to the same bytes: nothing in it is ignored.
  std::vector<std::uint8_t> again(nvm::record_bytes(sizeof(State)));
  if (nvm::encode_record(view.payload, view.payload_bytes, kTag, view.sequence, again.data(), again.size()) !=
          again.size() ||
      std::memcmp(again.data(), p, again.size()) != 0) {
    fail();
  }
  restore_and_tick(view.payload);
}

void store(const std::uint8_t* p, std::size_t n, bool fix) {
  MemNvm dev;
  const std::size_t m = n < dev.mem.size() ? n : dev.mem.size();
  if (m > 0) std::memcpy(dev.mem.data(), p, m);
  Store probe(dev, 0);
  const std::size_t stride = probe.footprint_bytes() / 2;
  if (fix) {
    fix_crc(dev.mem.data(), stride);
    fix_crc(dev.mem.data() + stride, stride);
  }
  // Independent verdict per slot.
  nvm::RecordView v[2];
  bool ok[2];
  for (int s = 0; s < 2; ++s) {
    ok[s] = nvm::check_record(dev.mem.data() + s * stride, Store::kRecordBytes, kTag, sizeof(State), v[s]) ==
            nvm::RecordCheck::valid;
  }
  int expect = -1;
  if (ok[0] && ok[1]) {
    expect = nvm::sequence_newer(v[1].sequence, v[0].sequence) ? 1 : 0;
  } else if (ok[0] || ok[1]) {
    expect = ok[0] ? 0 : 1;
  }
  Store st(dev, 0);
  State out;
  std::memset(&out, 0xA5, sizeof out);
  const nvm::StoreStatus s = st.load(out);
  if ((s == nvm::StoreStatus::ok) != (expect >= 0)) fail();
  if (expect >= 0) {
    if (st.newest_slot() != expect || std::memcmp(&out, v[expect].payload, sizeof out) != 0) fail();
    restore_and_tick(v[expect].payload);
  }
  // Whatever was there, a save commits and is what loads next, and the other slot keeps
  // the record that was newest before.
  const std::array<std::uint8_t, 1024> before = dev.mem;
  State next;
  std::memset(&next, 0x3C, sizeof next);
  if (st.save(next) != nvm::StoreStatus::ok) fail();
  const int written = st.newest_slot();
  if (expect >= 0 && written == expect) fail();
  Store again(dev, 0);
  State back;
  if (again.load(back) != nvm::StoreStatus::ok || std::memcmp(&back, &next, sizeof back) != 0) fail();
  if (expect >= 0 &&
      std::memcmp(dev.mem.data() + expect * stride, before.data() + expect * stride, Store::kRecordBytes) != 0) {
    fail();
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 1) return 0;
  const std::uint8_t mode = data[0];
  std::vector<std::uint8_t> bytes(data + 1, data + size);
  switch (mode % 3u) {
    case 0:
      decode(bytes.data(), bytes.size());
      break;
    case 1:
      fix_crc(bytes.data(), bytes.size());
      decode(bytes.data(), bytes.size());
      break;
    default:
      store(bytes.data(), bytes.size(), (mode & 0x80u) != 0u);
      break;
  }
  return 0;
}
