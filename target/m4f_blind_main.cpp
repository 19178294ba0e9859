// Blind identification on the board: the firmware's tick (replay_tick.hpp, best profile) over
// measured samples streamed from a file, not linked into flash, so that several cycles of a
// blind truth fit. The same source runs on the host in double (the reference) and in float,
// and on the Cortex-M4F under QEMU, where the file is read through semihosting (newlib's
// fopen/fread over rdimon: SYS_OPEN, SYS_READ). target/tools/m4f_blind.py writes the file
// from a truth.csv's measured columns, runs both builds and scores them.
//
//   host:   bms_m4f_blind_host MEASURED.bin > OUT.txt
//   board:  qemu-system-arm ... -semihosting -kernel bms_m4f_blind.elf   (reads ./measured.bin
//           relative to QEMU's working directory: the board has no command line)
//
// Input (little-endian): 8 bytes "BMSMEAS1", uint32 sample count, uint32 0, then per sample
// the measured voltage [V] and current [A, positive on discharge] as two IEEE doubles; each
// is rounded to the build's scalar as the host tools round a truth.csv's text.
// Output: "# columns", one line per tick with the estimates as hexadecimal bit patterns (exact,
// and cheap to print on a board without double hardware), "# name value" summary lines.
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>

#include "fw_source_hash.hpp"
#include "replay_tick.hpp"

namespace {

using bms::target::Scalar;

constexpr char kMagic[8] = {'B', 'M', 'S', 'M', 'E', 'A', 'S', '1'};
constexpr std::size_t kChunkSamples = 128u;  // 2 KiB per read: few semihosting calls, small RAM

struct MeasuredSample {
  double voltage_v;
  double current_a;
};
static_assert(sizeof(MeasuredSample) == 16u, "two packed doubles per sample");

// The value's bit pattern in hexadecimal: 8 digits for float, 16 for double.
void put_bits(Scalar v) {
  if constexpr (sizeof(Scalar) == sizeof(std::uint32_t)) {
    std::uint32_t bits = 0u;
    std::memcpy(&bits, &v, sizeof bits);
    std::printf(" %08lx", static_cast<unsigned long>(bits));
  } else {
    std::uint64_t bits = 0u;
    std::memcpy(&bits, &v, sizeof bits);
    // Two halves: newlib-nano's printf has no 64-bit conversions.
    std::printf(" %08lx%08lx", static_cast<unsigned long>(bits >> 32u), static_cast<unsigned long>(bits & 0xffffffffu));
  }
}

// Reads the header; returns the sample count, or -1 after printing why.
long read_header(std::FILE* in, const char* path) {
  char magic[8];
  std::uint32_t words[2];
  if (std::fread(magic, 1, sizeof magic, in) != sizeof magic || std::memcmp(magic, kMagic, sizeof magic) != 0 ||
      std::fread(words, sizeof words[0], 2, in) != 2u) {
    std::printf("# error %s: not a BMSMEAS1 file\n", path);
    return -1;
  }
  return static_cast<long>(words[0]);
}

struct RunTotals {
  std::uint32_t status_or = 0u;
  std::uint32_t cap_hits = 0u;
  bool finite = true;
};

void tick_and_print(bms::target::ReplayFirmware& fw, const MeasuredSample& s, unsigned long k, RunTotals& totals) {
  const auto out = bms::target::replay_tick(fw, static_cast<Scalar>(s.voltage_v), static_cast<Scalar>(s.current_a));
  std::printf("%lu %u %u", k, static_cast<unsigned>(out.mode), out.rcsi_active ? 1u : 0u);
  put_bits(out.r_film_est_ohm_m2);
  put_bits(out.growth_gain);
  put_bits(out.inventory_deviation);
  put_bits(out.z_v);
  std::printf("\n");
  totals.status_or |= out.status;
  if (bms::fw::has_status(out.status, bms::fw::FwStatus::kModelNotConverged)) ++totals.cap_hits;
  totals.finite = totals.finite && std::isfinite(out.r_film_est_ohm_m2) && std::isfinite(out.growth_gain);
}

// Streams the file through the tick in chunks. Exit status: 0, 1 (non-finite estimate or a
// short file), 2 (unreadable input).
int run(const char* path) {
  std::FILE* in = std::fopen(path, "rb");
  if (in == nullptr) {
    std::printf("# error %s: cannot open\n", path);
    return 2;
  }
  const long count = read_header(in, path);
  if (count < 0) return 2;
  static bms::target::ReplayFirmware fw;  // static: the firmware's state is RAM, not stack
  static MeasuredSample chunk[kChunkSamples];
  std::printf("# scalar %s\n", sizeof(Scalar) == sizeof(double) ? "double" : "float");
  std::printf("# source_hash %s\n", BMS_FW_SOURCE_HASH);
  std::printf("# columns tick mode active r_film gain nu z\n");
  RunTotals totals;
  unsigned long done = 0u;
  while (done < static_cast<unsigned long>(count)) {
    const std::size_t want = static_cast<unsigned long>(count) - done < kChunkSamples
                                 ? static_cast<std::size_t>(static_cast<unsigned long>(count) - done)
                                 : kChunkSamples;
    const std::size_t got = std::fread(chunk, sizeof chunk[0], want, in);
    for (std::size_t n = 0; n < got; ++n, ++done) tick_and_print(fw, chunk[n], done, totals);
    if (got != want) break;
  }
  std::fclose(in);
  std::printf("# ticks %lu of %ld\n", done, count);
  std::printf("# resyncs %u\n", static_cast<unsigned>(fw.core.resync_count()));
  std::printf("# status_or 0x%08x\n", static_cast<unsigned>(totals.status_or));
  std::printf("# newton_cap_hits %u\n", static_cast<unsigned>(totals.cap_hits));
  return totals.finite && done == static_cast<unsigned long>(count) ? 0 : 1;
}

}  // namespace

#ifdef BMS_TARGET_BOARD
int main() { return run("measured.bin"); }
#else
int main(int argc, char** argv) {
  if (argc != 2 || std::strcmp(argv[1], "--help") == 0) {
    std::fprintf(stderr, "usage: bms_m4f_blind_host MEASURED.bin > OUT.txt\n");
    return 2;
  }
  return run(argv[1]);
}
#endif
