// Blind identification on the board: the firmware's tick (replay_tick.hpp, best profile) over
// measured samples streamed from a file, not linked into flash, so that several cycles of a
// blind truth fit. The same source runs on the host in double (the reference) and in float,
// and on the Cortex-M4F under QEMU, where the file is read through semihosting (newlib's
// fopen/fread over rdimon: SYS_OPEN, SYS_READ). target/tools/m4f_blind.py writes the file
// from a truth.csv's measured columns, runs both builds and scores them.
//
//   host:   bms_m4f_blind_host MEASURED.bin > OUT.txt
//   board:  qemu-system-arm ... -semihosting -icount shift=0,sleep=off -kernel bms_m4f_blind.elf
//           (reads ./measured.bin relative to QEMU's working directory: the board has no
//           command line)
//
// Input (little-endian): 8 bytes of format name, uint32 sample count, uint32 0, then per sample
//   BMSMEAS1: the measured voltage [V] and current [A, positive on discharge], two IEEE doubles;
//   BMSMEAS2: the same and the measured cell temperature [K] (a truth.csv's temperature_meas_k),
//             three IEEE doubles;
//   BMSMEAS3: a cycler record as `bmssim estimate --write-firmware-stream` ran it: after the
//             header three doubles (the model tick [s], the record's sample step when coarser
//             than the tick [s] or 0, learning 1 or 0: the firmware is configured as estimate's,
//             record_config), then per sample voltage, current, temperature (0: none) and the
//             ticks missed before it (BmsCore::ticks_missed), four IEEE doubles.
// Each value is rounded to the build's scalar as the host tools round a truth.csv's text. The
// temperature goes to the tick as `bmssim estimate` passes it (TickInput::temperature_k); a
// BMSMEAS1 file, or a 0 in a BMSMEAS2 sample, passes none (the model stays at the last accepted
// temperature, at power-up the cell's reference temperature).
// Output: "# columns", one line per tick (the last column the model's voltage) with the estimates as hexadecimal bit patterns (exact,
// and cheap to print on a board without double hardware), "# name value" summary lines; on the
// board (QEMU -icount shift=0) the costliest tick's instructions overall and per mode (0 on
// the host).
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <new>

#include "fw_source_hash.hpp"
#include "platform.hpp"
#include "replay_tick.hpp"

namespace {

using bms::target::Scalar;

constexpr char kMagicVi[8] = {'B', 'M', 'S', 'M', 'E', 'A', 'S', '1'};   // voltage, current
constexpr char kMagicVit[8] = {'B', 'M', 'S', 'M', 'E', 'A', 'S', '2'};  // and temperature
constexpr char kMagicRecord[8] = {'B', 'M', 'S', 'M', 'E', 'A', 'S', '3'};  // a cycler record
constexpr std::size_t kMaxFields = 4u;
constexpr std::size_t kChunkSamples = 128u;  // 3 KiB per read at most: few semihosting calls, small RAM
constexpr unsigned kModes = 8u;              // bms::fw::Mode's values fit below

struct MeasuredSample {
  double voltage_v;
  double current_a;
  double temperature_k;  // 0: none measured
  double missed_ticks;   // ticks without a sample before this one (BMSMEAS3)
};

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

struct Header {
  long count = -1;         // -1: not a measured-samples file
  std::size_t fields = 0;  // doubles per sample: 2 (BMSMEAS1), 3 (BMSMEAS2) or 4 (BMSMEAS3)
  double record[3] = {};   // BMSMEAS3: model tick [s], sample step [s], learning
};

// Reads the header; count -1 after printing why.
Header read_header(std::FILE* in, const char* path) {
  char magic[8];
  std::uint32_t words[2];
  Header h;
  if (std::fread(magic, 1, sizeof magic, in) == sizeof magic && std::fread(words, sizeof words[0], 2, in) == 2u) {
    if (std::memcmp(magic, kMagicVi, sizeof magic) == 0) h.fields = 2u;
    if (std::memcmp(magic, kMagicVit, sizeof magic) == 0) h.fields = 3u;
    if (std::memcmp(magic, kMagicRecord, sizeof magic) == 0) h.fields = 4u;
  }
  const bool record_ok = h.fields != 4u || std::fread(h.record, sizeof h.record[0], 3, in) == 3u;
  if (h.fields == 0u || words[1] != 0u || !record_ok || (h.fields == 4u && !(h.record[0] > 0.0))) {
    std::printf("# error %s: not a BMSMEAS1, BMSMEAS2 or BMSMEAS3 file\n", path);
    h.count = -1;
    return h;
  }
  h.count = static_cast<long>(words[0]);
  return h;
}

struct RunTotals {
  std::uint32_t status_or = 0u;
  std::uint32_t cap_hits = 0u;
  std::uint32_t temperature_refused = 0u;
  bool finite = true;
  std::uint64_t worst_instructions = 0u;  // the costliest tick (board only)
  unsigned long worst_tick = 0u;
  unsigned worst_mode = 0u;
  std::uint64_t worst_by_mode[kModes] = {};
  std::uint64_t total_instructions = 0u;
};

void count_cost(std::uint64_t instructions, unsigned long k, unsigned mode, RunTotals& totals) {
  totals.total_instructions += instructions;
  if (mode < kModes && instructions > totals.worst_by_mode[mode]) totals.worst_by_mode[mode] = instructions;
  if (instructions <= totals.worst_instructions) return;
  totals.worst_instructions = instructions;
  totals.worst_tick = k;
  totals.worst_mode = mode;
}

// A count of missed ticks as the core takes it (32-bit chunks, as estimate tells it).
void tell_missed(bms::target::ReplayFirmware& fw, double missed) {
  while (missed > 0.0) {
    const double chunk = missed < 2147483647.0 ? missed : 2147483647.0;
    fw.core.ticks_missed(static_cast<std::uint32_t>(chunk));
    missed -= chunk;
  }
}

void tick_and_print(bms::target::ReplayFirmware& fw, const MeasuredSample& s, unsigned long k, RunTotals& totals) {
  tell_missed(fw, s.missed_ticks);
  const std::uint64_t t0 = bms::target::platform_instructions();
  const auto out = bms::target::replay_tick(fw, static_cast<Scalar>(s.voltage_v), static_cast<Scalar>(s.current_a),
                                            static_cast<Scalar>(s.temperature_k));
  const std::uint64_t t1 = bms::target::platform_instructions();
  std::printf("%lu %u %u", k, static_cast<unsigned>(out.mode), out.rcsi_active ? 1u : 0u);
  put_bits(out.r_film_est_ohm_m2);
  put_bits(out.growth_gain);
  put_bits(out.inventory_deviation);
  put_bits(out.z_v);
  put_bits(out.capacity_ah);
  put_bits(out.model_voltage_v);
  std::printf("\n");
  count_cost(t1 - t0, k, static_cast<unsigned>(out.mode), totals);
  totals.status_or |= out.status;
  if (bms::fw::has_status(out.status, bms::fw::FwStatus::kModelNotConverged)) ++totals.cap_hits;
  if (bms::fw::has_status(out.status, bms::fw::FwStatus::kTemperatureImplausible)) ++totals.temperature_refused;
  totals.finite = totals.finite && std::isfinite(out.r_film_est_ohm_m2) && std::isfinite(out.growth_gain);
}

// Sample n of a chunk of `fields` doubles per sample (BMSMEAS1: no temperature).
MeasuredSample sample_at(const double* raw, std::size_t n, std::size_t fields) {
  const double* p = raw + n * fields;
  return {p[0], p[1], fields > 2u ? p[2] : 0.0, fields > 3u ? p[3] : 0.0};
}

void print_summary(const bms::target::ReplayFirmware& fw, const RunTotals& totals, unsigned long done, long count,
                   std::uint64_t counter_overhead) {
  std::printf("# ticks %lu of %ld\n", done, count);
  std::printf("# resyncs %u\n", static_cast<unsigned>(fw.core.resync_count()));
  std::printf("# status_or 0x%08x\n", static_cast<unsigned>(totals.status_or));
  std::printf("# newton_cap_hits %u\n", static_cast<unsigned>(totals.cap_hits));
  std::printf("# temperature_refused_ticks %u\n", static_cast<unsigned>(totals.temperature_refused));
  std::printf("# temperature_k_end %.6f\n", static_cast<double>(fw.model.temperature_k()));
  std::printf("# worst_tick_instructions %lu tick %lu mode %u\n", static_cast<unsigned long>(totals.worst_instructions),
              totals.worst_tick, totals.worst_mode);
  for (unsigned m = 0; m < kModes; ++m) {
    if (totals.worst_by_mode[m] != 0u) {
      std::printf("# worst_tick_instructions_mode%u %lu\n", m, static_cast<unsigned long>(totals.worst_by_mode[m]));
    }
  }
  std::printf("# mean_tick_instructions %lu\n",
              static_cast<unsigned long>(done != 0u ? totals.total_instructions / done : 0u));
  std::printf("# counter_overhead_instructions %lu\n", static_cast<unsigned long>(counter_overhead));
  std::printf("# firmware_state_bytes %u\n", static_cast<unsigned>(sizeof(fw)));
}

// Streams the file through the tick in chunks. Exit status: 0, 1 (non-finite estimate or a
// short file), 2 (unreadable input).
int run(const char* path) {
  std::FILE* in = std::fopen(path, "rb");
  if (in == nullptr) {
    std::printf("# error %s: cannot open\n", path);
    return 2;
  }
  const Header header = read_header(in, path);
  if (header.count < 0) return 2;
  const long count = header.count;
  bms::target::platform_start();
  const std::uint64_t c0 = bms::target::platform_instructions();
  const std::uint64_t c1 = bms::target::platform_instructions();
  // Static storage: the firmware's state is RAM, not stack; built in place (no heap) once the
  // header says how (a record: estimate's configuration; else the image's own).
  alignas(bms::target::ReplayFirmware) static unsigned char storage[sizeof(bms::target::ReplayFirmware)];
  bms::target::ReplayFirmware& fw =
      header.fields == 4u ? *new (storage) bms::target::ReplayFirmware(bms::target::record_config(
                                header.record[0], header.record[1], header.record[2] != 0.0))
                          : *new (storage) bms::target::ReplayFirmware();
  static double raw[kChunkSamples * kMaxFields];
  std::printf("# scalar %s\n", sizeof(Scalar) == sizeof(double) ? "double" : "float");
  std::printf("# source_hash %s\n", BMS_FW_SOURCE_HASH);
  static const char* const kFormat[] = {"", "", "BMSMEAS1", "BMSMEAS2", "BMSMEAS3"};
  std::printf("# format %s\n", kFormat[header.fields]);
  std::printf("# cell %s\n", bms::target::Cell::kName);
  if (header.fields == 4u)
    std::printf("# record tick_s %.9f sample_step_s %.9f learning %d\n", header.record[0], header.record[1],
                header.record[2] != 0.0 ? 1 : 0);
  std::printf("# columns tick mode active r_film gain nu z capacity model_v\n");
  RunTotals totals;
  unsigned long done = 0u;
  while (done < static_cast<unsigned long>(count)) {
    const std::size_t want = static_cast<unsigned long>(count) - done < kChunkSamples
                                 ? static_cast<std::size_t>(static_cast<unsigned long>(count) - done)
                                 : kChunkSamples;
    const std::size_t got = std::fread(raw, sizeof raw[0] * header.fields, want, in);
    for (std::size_t n = 0; n < got; ++n, ++done) tick_and_print(fw, sample_at(raw, n, header.fields), done, totals);
    if (got != want) break;
  }
  std::fclose(in);
  print_summary(fw, totals, done, count, c1 - c0);
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
