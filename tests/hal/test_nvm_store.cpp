// Two-slot NVM record store (firmware/include/bms/fw/nvm/nvm_store.hpp): record codec, CRC-32,
// sequence wraparound, and persistence through power loss: a write cut at every byte
// offset of a record, over several successive commits that use both slots and wrap the
// sequence number, must always leave the last committed state loadable and never let a
// torn record be accepted.
#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <random>
#include <string>
#include <vector>

#include "bms/fw/nvm/nvm_store.hpp"
#include "bms/fw/estimation/rcsi_estimator.hpp"
#include "../common/rcsi_test_config.hpp"
#include "bms/hal/fake/fake_nvm.hpp"
#include "bms/hal/linux/file_nvm.hpp"
#include "bms/hal/nvm.hpp"

namespace nvm = bms::fw::nvm;
namespace hal = bms::hal;
using nvm::RecordCheck;
using nvm::StoreStatus;

namespace {

// The store treats a value-initialised status as success; the HAL must keep ok == 0.
static_assert(hal::Status{} == hal::Status::ok, "nvm_store.hpp relies on Status::ok being 0");
static_assert(nvm::kErasedByte == hal::kNvmErasedByte, "one erased-byte value");

using Estimator = bms::fw::RcsiEstimator<double, 2, 1>;
using State = Estimator::State;
using Store = nvm::RecordStore<State, Estimator::kLayoutTag, hal::fake::RamNvm>;

constexpr std::size_t kPage = 64;
constexpr std::size_t kNvmBytes = 2048;
constexpr std::size_t kBase = 256;  // not at 0: the store must honour its base offset

Estimator::Config config() { return bms::test::rcsi_test_config<Estimator>(); }

// Successive, all different estimator states: what the firmware saves once per commit.
std::vector<State> estimator_states(int count) {
  Estimator est(config());
  std::mt19937 rng(7u);
  std::normal_distribution<double> normal(0.0, 1.0);
  std::vector<State> out;
  for (int i = 0; i < count; ++i) {
    for (int k = 0; k < 5; ++k) {
      est.predict();
      est.update(1e-5 * normal(rng), -10.0 + normal(rng));
    }
    out.push_back(est.save());
  }
  return out;
}

bool same(const State& a, const State& b) { return std::memcmp(&a, &b, sizeof(State)) == 0; }

std::vector<std::uint8_t> encoded(const State& s, std::uint32_t seq, std::uint32_t tag = Estimator::kLayoutTag) {
  std::vector<std::uint8_t> rec(nvm::record_bytes(sizeof(State)));
  EXPECT_EQ(nvm::encode_record(&s, sizeof s, tag, seq, rec.data(), rec.size()), rec.size());
  return rec;
}

RecordCheck check(const std::vector<std::uint8_t>& rec, std::uint32_t tag = Estimator::kLayoutTag) {
  nvm::RecordView view;
  return nvm::check_record(rec.data(), rec.size(), tag, sizeof(State), view);
}

// Cuts the next erase after `n` bytes (the first n bytes of the span erased, the rest
// unchanged, io_error), as a power loss during a flash erase; everything else passes to
// the RAM NVM. RamNvm's own fail_next_erase() only models an erase that does nothing.
class EraseCutNvm {
 public:
  explicit EraseCutNvm(hal::fake::RamNvm& ram) : ram_(ram) {}
  std::size_t size_bytes() const { return ram_.size_bytes(); }
  std::size_t page_size() const { return ram_.page_size(); }
  hal::Status read(std::size_t o, void* d, std::size_t n) { return ram_.read(o, d, n); }
  hal::Status write(std::size_t o, const void* s, std::size_t n) { return ram_.write(o, s, n); }
  hal::Status erase(std::size_t o, std::size_t n) {
    if (!armed_) return ram_.erase(o, n);
    armed_ = false;
    const std::vector<std::uint8_t> ff(std::min(cut_, n), hal::kNvmErasedByte);
    if (!ff.empty()) {
      EXPECT_EQ(ram_.write(o, ff.data(), ff.size()), hal::Status::ok);
    }
    return hal::Status::io_error;
  }
  void cut_next_erase_at(std::size_t n) {
    armed_ = true;
    cut_ = n;
  }

 private:
  hal::fake::RamNvm& ram_;
  bool armed_ = false;
  std::size_t cut_ = 0;
};

// A device whose writes report success but store nothing (worn-out flash, a write-protect
// pin): only the read-back can notice.
class SilentWriteNvm {
 public:
  explicit SilentWriteNvm(hal::fake::RamNvm& ram) : ram_(ram) {}
  std::size_t size_bytes() const { return ram_.size_bytes(); }
  std::size_t page_size() const { return ram_.page_size(); }
  hal::Status read(std::size_t o, void* d, std::size_t n) { return ram_.read(o, d, n); }
  hal::Status write(std::size_t, const void*, std::size_t) { return hal::Status::ok; }
  hal::Status erase(std::size_t o, std::size_t n) { return ram_.erase(o, n); }

 private:
  hal::fake::RamNvm& ram_;
};

}  // namespace

// ---------------------------------------------------------------- codec

TEST(NvmRecord, Crc32MatchesTheCatalogueCheckValue) {
  const char* s = "123456789";
  EXPECT_EQ(nvm::crc32(reinterpret_cast<const std::uint8_t*>(s), 9), 0xCBF43926u);
  EXPECT_EQ(nvm::crc32(nullptr, 0), 0u);
  static constexpr std::uint8_t kA[] = {'a'};
  static_assert(nvm::crc32(kA, 1) == 0xE8B7BE43u, "usable in constant expressions");
}

TEST(NvmRecord, SequenceComparisonSurvivesWraparound) {
  EXPECT_TRUE(nvm::sequence_newer(2, 1));
  EXPECT_FALSE(nvm::sequence_newer(1, 2));
  EXPECT_FALSE(nvm::sequence_newer(5, 5));
  EXPECT_TRUE(nvm::sequence_newer(0, 0xFFFFFFFFu));
  EXPECT_FALSE(nvm::sequence_newer(0xFFFFFFFFu, 0));
  EXPECT_TRUE(nvm::sequence_newer(3, 0xFFFFFFFEu));
  // Half the range apart: foreign data, neither is newer (no flip-flopping).
  EXPECT_FALSE(nvm::sequence_newer(0x80000000u, 0));
  EXPECT_FALSE(nvm::sequence_newer(0, 0x80000000u));
  EXPECT_TRUE(nvm::sequence_newer(0x7FFFFFFFu, 0));
}

TEST(NvmRecord, RoundTripAndLayoutIsLittleEndian) {
  const State s = estimator_states(1)[0];
  const auto rec = encoded(s, 0x01020304u);
  ASSERT_EQ(rec.size(), 20u + sizeof(State) + 4u);
  EXPECT_EQ(rec[0], 'B');
  EXPECT_EQ(rec[3], 'N');
  EXPECT_EQ(rec[4], 1u);   // format version
  EXPECT_EQ(rec[12], 0x04u);  // sequence, least significant byte first
  EXPECT_EQ(rec[15], 0x01u);
  EXPECT_EQ(rec[16], static_cast<std::uint8_t>(sizeof(State)));
  nvm::RecordView view;
  ASSERT_EQ(nvm::check_record(rec.data(), rec.size(), Estimator::kLayoutTag, sizeof(State), view),
            RecordCheck::valid);
  EXPECT_EQ(view.sequence, 0x01020304u);
  EXPECT_EQ(view.payload_bytes, sizeof(State));
  EXPECT_EQ(std::memcmp(view.payload, &s, sizeof s), 0);
  std::uint8_t small[100];
  EXPECT_EQ(nvm::encode_record(&s, sizeof s, 1, 1, small, sizeof small), 0u);
}

TEST(NvmRecord, RejectsEveryKindOfBadRecord) {
  const State s = estimator_states(1)[0];
  const auto good = encoded(s, 9);
  EXPECT_EQ(check(std::vector<std::uint8_t>(good.size(), 0xFF)), RecordCheck::erased);
  EXPECT_EQ(check(std::vector<std::uint8_t>(good.size(), 0x00)), RecordCheck::bad_magic);
  EXPECT_EQ(check(std::vector<std::uint8_t>(good.begin(), good.begin() + 23)), RecordCheck::truncated);
  // Cut short: the stored length no longer fits.
  EXPECT_EQ(check(std::vector<std::uint8_t>(good.begin(), good.end() - 1)), RecordCheck::bad_length);
  auto rec = good;
  rec[16] = 0xFF;  // length beyond the buffer
  EXPECT_EQ(check(rec), RecordCheck::bad_length);
  rec = good;
  rec[40] ^= 0x01;
  EXPECT_EQ(check(rec), RecordCheck::bad_crc);
  // Another payload type with a good CRC is refused by its tag; another length too.
  EXPECT_EQ(check(encoded(s, 9, Estimator::kLayoutTag + 1)), RecordCheck::bad_layout);
  std::vector<std::uint8_t> shorter(nvm::record_bytes(8) + 100);
  ASSERT_NE(nvm::encode_record(&s, 8, Estimator::kLayoutTag, 1, shorter.data(), shorter.size()), 0u);
  EXPECT_EQ(check(shorter), RecordCheck::bad_length);
  // A future format version (CRC recomputed) is refused, not misread.
  rec = good;
  rec[4] = 2;
  const std::size_t crc_at = rec.size() - 4;
  const std::uint32_t crc = nvm::crc32(rec.data(), crc_at);
  for (int i = 0; i < 4; ++i) rec[crc_at + i] = static_cast<std::uint8_t>(crc >> (8 * i));
  EXPECT_EQ(check(rec), RecordCheck::bad_version);
}

TEST(NvmRecord, EverySingleBitFlipIsRejected) {
  const auto good = encoded(estimator_states(1)[0], 77);
  int accepted = 0;
  for (std::size_t bit = 0; bit < good.size() * 8; ++bit) {
    auto rec = good;
    rec[bit / 8] = static_cast<std::uint8_t>(rec[bit / 8] ^ (1u << (bit % 8)));
    if (check(rec) == RecordCheck::valid) ++accepted;
  }
  EXPECT_EQ(accepted, 0) << "of " << good.size() * 8 << " flipped bits";
}

// ---------------------------------------------------------------- store

TEST(NvmStore, NewDeviceIsEmptyThenCommitsAlternateSlots) {
  hal::fake::RamNvm ram(kNvmBytes, kPage);
  const auto states = estimator_states(4);
  Store store(ram, kBase);
  ASSERT_TRUE(store.config_ok());
  EXPECT_EQ(store.footprint_bytes(), 2 * 320u);  // 296-byte record in 5 pages of 64
  State out{};
  EXPECT_EQ(store.load(out), StoreStatus::empty);
  EXPECT_FALSE(store.has_record());
  for (int i = 0; i < 4; ++i) {
    ASSERT_EQ(store.save(states[i]), StoreStatus::ok) << ram.last_error();
    EXPECT_EQ(store.newest_slot(), i % 2);
    EXPECT_EQ(store.newest_sequence(), static_cast<std::uint32_t>(i + 1));
  }
  // Nothing outside the two slots was touched.
  for (std::size_t i = 0; i < ram.size_bytes(); ++i) {
    if (i < kBase || i >= kBase + store.footprint_bytes()) {
      ASSERT_EQ(ram.bytes()[i], 0xFF) << i;
    }
  }
  Store after_reboot(ram, kBase);
  ASSERT_EQ(after_reboot.load(out), StoreStatus::ok);
  EXPECT_TRUE(same(out, states[3]));
  EXPECT_EQ(after_reboot.newest_slot(), 1);
  EXPECT_EQ(after_reboot.slot_check(0), RecordCheck::valid);
  EXPECT_EQ(after_reboot.slot_sequence(0), 3u);
  // The restored image is accepted by a fresh estimator and saves back bit-identically.
  Estimator est(config());
  ASSERT_TRUE(est.restore(out));
  EXPECT_TRUE(same(est.save(), states[3]));
}

TEST(NvmStore, SaveWithoutLoadNeverOverwritesTheNewestRecord) {
  hal::fake::RamNvm ram(kNvmBytes, kPage);
  const auto states = estimator_states(3);
  {
    Store store(ram, kBase);
    ASSERT_EQ(store.save(states[0]), StoreStatus::ok);
    ASSERT_EQ(store.save(states[1]), StoreStatus::ok);  // newest in slot 1
  }
  Store store(ram, kBase);
  ASSERT_EQ(store.save(states[2]), StoreStatus::ok);  // must go to slot 0
  EXPECT_EQ(store.newest_slot(), 0);
  EXPECT_EQ(store.newest_sequence(), 3u);
  State out{};
  ASSERT_EQ(Store(ram, kBase).load(out), StoreStatus::ok);
  EXPECT_TRUE(same(out, states[2]));
}

TEST(NvmStore, RejectsBadPlacement) {
  hal::fake::RamNvm ram(kNvmBytes, kPage);
  State out{};
  Store unaligned(ram, 100);
  EXPECT_FALSE(unaligned.config_ok());
  EXPECT_EQ(unaligned.load(out), StoreStatus::invalid_config);
  EXPECT_EQ(unaligned.save(out), StoreStatus::invalid_config);
  EXPECT_FALSE(Store(ram, kNvmBytes - 512).config_ok());  // 2 x 320 bytes do not fit
  EXPECT_TRUE(Store(ram, kNvmBytes - 640).config_ok());
  EXPECT_FALSE(Store(ram, kNvmBytes + kPage).config_ok());
  EXPECT_EQ(ram.writes() + ram.erases(), 0u);
}

TEST(NvmStore, SequenceWrapsAroundAndTheNewerRecordStillWins) {
  hal::fake::RamNvm ram(kNvmBytes, kPage);
  const auto states = estimator_states(4);
  Store probe(ram, kBase);
  // Records as a long-lived device would hold them: sequences just before the wrap.
  const auto r0 = encoded(states[0], 0xFFFFFFFFu);
  const auto r1 = encoded(states[1], 0xFFFFFFFEu);
  ASSERT_EQ(ram.write(probe.slot_offset(0), r0.data(), r0.size()), hal::Status::ok);
  ASSERT_EQ(ram.write(probe.slot_offset(1), r1.data(), r1.size()), hal::Status::ok);
  State out{};
  Store store(ram, kBase);
  ASSERT_EQ(store.load(out), StoreStatus::ok);
  EXPECT_TRUE(same(out, states[0]));
  ASSERT_EQ(store.save(states[2]), StoreStatus::ok);
  EXPECT_EQ(store.newest_sequence(), 0u);
  EXPECT_EQ(store.newest_slot(), 1);
  ASSERT_EQ(Store(ram, kBase).load(out), StoreStatus::ok);
  EXPECT_TRUE(same(out, states[2])) << "sequence 0 is newer than 0xFFFFFFFF";
  ASSERT_EQ(store.save(states[3]), StoreStatus::ok);
  EXPECT_EQ(store.newest_sequence(), 1u);
  ASSERT_EQ(Store(ram, kBase).load(out), StoreStatus::ok);
  EXPECT_TRUE(same(out, states[3]));
}

TEST(NvmStore, ForeignOrCorruptContentIsAFaultNotAState) {
  hal::fake::RamNvm ram(kNvmBytes, kPage);
  const auto states = estimator_states(2);
  {
    // Records of another estimator instantiation (another layout tag) in both slots.
    nvm::RecordStore<State, Estimator::kLayoutTag ^ 0x10u, hal::fake::RamNvm> other(ram, kBase);
    ASSERT_EQ(other.save(states[0]), StoreStatus::ok);
    ASSERT_EQ(other.save(states[1]), StoreStatus::ok);
  }
  Store store(ram, kBase);
  State out = states[1];
  EXPECT_EQ(store.load(out), StoreStatus::no_valid_record);
  EXPECT_EQ(store.slot_check(0), RecordCheck::bad_layout);
  EXPECT_TRUE(same(out, states[1])) << "output untouched";
  // Saving over foreign content works and is then found.
  ASSERT_EQ(store.save(states[0]), StoreStatus::ok);
  ASSERT_EQ(Store(ram, kBase).load(out), StoreStatus::ok);
  EXPECT_TRUE(same(out, states[0]));
}

TEST(NvmStore, EraseFailureAndSilentWriteFailureAreReportedAndLoseNothing) {
  hal::fake::RamNvm ram(kNvmBytes, kPage);
  const auto states = estimator_states(3);
  Store store(ram, kBase);
  ASSERT_EQ(store.save(states[0]), StoreStatus::ok);
  ram.fail_next_erase();
  EXPECT_EQ(store.save(states[1]), StoreStatus::io_error);
  State out{};
  ASSERT_EQ(Store(ram, kBase).load(out), StoreStatus::ok);
  EXPECT_TRUE(same(out, states[0]));

  SilentWriteNvm silent(ram);
  nvm::RecordStore<State, Estimator::kLayoutTag, SilentWriteNvm> lying(silent, kBase);
  EXPECT_EQ(lying.save(states[2]), StoreStatus::io_error) << "the read-back must catch it";
  ASSERT_EQ(Store(ram, kBase).load(out), StoreStatus::ok);
  EXPECT_TRUE(same(out, states[0]));
}

// The sweep the issue asks for. For each of several successive commits, from a device
// state that already holds the previous commits: cut the record's write after n bytes for
// every n = 0..record length (n = length: every byte landed but the write still reported
// a failure), reboot, load. The load must return the last committed state (for n = length
// the new state is also correct: it is byte for byte a complete record); anything else is
// a lost record, and a state that is neither is a torn record accepted. Then the rebooted
// store must commit the new state over the torn slot. Erases cut part-way are swept too.
TEST(NvmStore, PowerCutAtEveryByteOfEveryCommitLosesNothing) {
  constexpr int kCommits = 6;  // both slots three times each; crosses the sequence wrap
  const auto states = estimator_states(kCommits + 1);
  hal::fake::RamNvm device(kNvmBytes, kPage);
  {
    // Start two commits before the wrap, so the sweep covers 0xFFFFFFFF -> 0 as well.
    Store probe(device, kBase);
    const auto r = encoded(states[0], 0xFFFFFFFEu);
    ASSERT_EQ(device.write(probe.slot_offset(0), r.data(), r.size()), hal::Status::ok);
  }
  const std::size_t record = Store::kRecordBytes;
  int write_cuts = 0, erase_cuts = 0, lost = 0, torn_accepted = 0, recovered_commits = 0;
  for (int c = 1; c <= kCommits; ++c) {
    const State& committed = states[c - 1];
    const State& next = states[c];
    for (std::size_t n = 0; n <= record; ++n) {
      hal::fake::RamNvm ram = device;  // the device as the previous commit left it
      {
        Store store(ram, kBase);
        ram.tear_next_write_at(n);
        ASSERT_EQ(store.save(next), StoreStatus::io_error) << "commit " << c << " cut at " << n;
      }
      ++write_cuts;
      State out{};
      Store rebooted(ram, kBase);
      const StoreStatus s = rebooted.load(out);
      const bool is_committed = s == StoreStatus::ok && same(out, committed);
      const bool is_next = s == StoreStatus::ok && same(out, next);
      if (!(is_committed || (n == record && is_next))) {
        ++lost;
        ADD_FAILURE() << "commit " << c << ", write cut at byte " << n << ": " << nvm::store_status_name(s);
      }
      if (s == StoreStatus::ok && !is_committed && !is_next) ++torn_accepted;
      if (is_next && n < record) ++torn_accepted;
      // Recovery: the next save after the reboot commits over the torn slot.
      ASSERT_EQ(rebooted.save(next), StoreStatus::ok);
      ASSERT_EQ(Store(ram, kBase).load(out), StoreStatus::ok);
      if (same(out, next)) ++recovered_commits;
    }
    // Power loss during the erase of the target slot (which holds the commit before last).
    const std::size_t stride = Store(device, kBase).footprint_bytes() / 2;
    for (std::size_t n = 0; n <= stride; n += 1) {
      hal::fake::RamNvm ram = device;
      EraseCutNvm cutter(ram);
      {
        nvm::RecordStore<State, Estimator::kLayoutTag, EraseCutNvm> store(cutter, kBase);
        cutter.cut_next_erase_at(n);
        ASSERT_EQ(store.save(next), StoreStatus::io_error);
      }
      ++erase_cuts;
      State out{};
      const StoreStatus s = Store(ram, kBase).load(out);
      if (!(s == StoreStatus::ok && same(out, committed))) {
        ++lost;
        ADD_FAILURE() << "commit " << c << ", erase cut at byte " << n << ": " << nvm::store_status_name(s);
      }
    }
    Store store(device, kBase);
    ASSERT_EQ(store.save(next), StoreStatus::ok);
  }
  State out{};
  Store final_store(device, kBase);
  ASSERT_EQ(final_store.load(out), StoreStatus::ok);
  EXPECT_TRUE(same(out, states[kCommits]));
  EXPECT_EQ(final_store.newest_sequence(), 0xFFFFFFFEu + kCommits);  // wrapped

  std::printf("[nvm power-cut] record %zu bytes, %d commits: %d write cut points + %d erase cut points = %d "
              "tried, records lost %d, torn records accepted %d, recovered commits %d/%d\n",
              record, kCommits, write_cuts, erase_cuts, write_cuts + erase_cuts, lost, torn_accepted,
              recovered_commits, write_cuts);
  ::testing::Test::RecordProperty("cut_points", write_cuts + erase_cuts);
  ::testing::Test::RecordProperty("records_lost", lost);
  ::testing::Test::RecordProperty("torn_accepted", torn_accepted);
  EXPECT_EQ(write_cuts, kCommits * static_cast<int>(record + 1));
  EXPECT_EQ(lost, 0);
  EXPECT_EQ(torn_accepted, 0);
  EXPECT_EQ(recovered_commits, write_cuts);
}

// The first commit on a new device, cut anywhere: nothing was committed, so nothing may be
// loaded (empty when nothing landed, no_valid_record otherwise): never a torn state.
TEST(NvmStore, PowerCutDuringTheFirstCommitLoadsNothing) {
  const State s = estimator_states(1)[0];
  int accepted = 0;
  for (std::size_t n = 0; n < Store::kRecordBytes; ++n) {
    hal::fake::RamNvm ram(kNvmBytes, kPage);
    ram.tear_next_write_at(n);
    ASSERT_EQ(Store(ram, kBase).save(s), StoreStatus::io_error);
    State out{};
    const StoreStatus st = Store(ram, kBase).load(out);
    EXPECT_EQ(st, n == 0 ? StoreStatus::empty : StoreStatus::no_valid_record) << n;
    if (st == StoreStatus::ok) ++accepted;
  }
  EXPECT_EQ(accepted, 0);
}

// Through the abstract HAL interface and the Linux file backend: what the firmware process
// in the host-in-the-loop uses, across a process restart (the file reopened).
TEST(NvmStore, WorksThroughTheHalInterfaceOnAFile) {
  char dir_template[] = "/tmp/bms_nvm_store_XXXXXX";
  ASSERT_NE(::mkdtemp(dir_template), nullptr);
  const std::string path = std::string(dir_template) + "/nvm.bin";
  const auto states = estimator_states(3);
  using HalStore = nvm::RecordStore<State, Estimator::kLayoutTag, hal::NonVolatileMemory>;
  {
    hal::lnx::FileNvm file;
    ASSERT_EQ(file.open(path.c_str(), 4096, 512), hal::Status::ok) << file.last_error();
    hal::NonVolatileMemory& dev = file;
    HalStore store(dev, 0);
    for (const State& s : states) ASSERT_EQ(store.save(s), StoreStatus::ok) << file.last_error();
  }
  hal::lnx::FileNvm file;
  ASSERT_EQ(file.open(path.c_str(), 4096, 512), hal::Status::ok) << file.last_error();
  HalStore store(file, 0);
  State out{};
  ASSERT_EQ(store.load(out), StoreStatus::ok);
  EXPECT_TRUE(same(out, states[2]));
  EXPECT_EQ(store.newest_sequence(), 3u);
  file.close();
  std::remove(path.c_str());
  ::rmdir(dir_template);
}
