// Fuzz target: restoring the payload the firmware really commits (BmsApplication::Persisted of
// the firmware's core, BmsCore<double, ReducedCell<double>, 1, 0>) from non-volatile memory.
//
// A real image is made once (the core driven through a discharge and a CC charge by a second
// model). Each input patches it and stores it as a record with a correct CRC in one slot (so
// the fuzzer does not have to solve a CRC-32), optionally the unpatched image in the other:
//   byte 0: bit 0 the other slot holds the unpatched image (older sequence), bit 1 the
//   patched record's layout tag is replaced by bytes 1..4.
//   then patches of 10 bytes: [offset lo] [offset hi] [8 bytes written at offset % size]
//   (whole doubles such as 1e308, NaN or -0 land on field boundaries often enough).
// Then RecordStore::load() and BmsCore::restore(). Checked beyond "no crash, no UB":
// - a record with another layout tag is never loaded;
// - whenever restore() accepts an image, the next ticks (rest, CC charge, a missing sample)
//   give finite outputs: the range checks let nothing through that breaks the arithmetic;
// - a rejected image leaves the core as it was (its next output equals a fresh core's).
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>

#include "bms/fw/estimation/bms_core.hpp"
#include "bms/fw/nvm/nvm_store.hpp"
#include "bms/fw/config/make_config.hpp"
#include "bms/app/bms_application.hpp"

namespace fw = bms::fw;
namespace hal = bms::hal;

namespace {

using Model = fw::ReducedCell<double>;
using Core = fw::BmsCore<double, Model, 1, 0>;
using App = bms::app::BmsApplication<Core>;
using Persisted = App::Persisted;

[[noreturn]] void fail() { std::abort(); }

class MemNvm {
 public:
  enum class Status : std::uint8_t { ok = 0, out_of_range };
  std::size_t size_bytes() const { return sizeof mem; }
  std::size_t page_size() const { return 64; }
  Status read(std::size_t o, void* d, std::size_t n) {
    if (o > sizeof mem || n > sizeof mem - o) return Status::out_of_range;
    std::memcpy(d, mem + o, n);
    return Status::ok;
  }
  Status write(std::size_t o, const void* s, std::size_t n) {
    if (o > sizeof mem || n > sizeof mem - o) return Status::out_of_range;
    std::memcpy(mem + o, s, n);
    return Status::ok;
  }
  Status erase(std::size_t o, std::size_t n) {
    if (o > sizeof mem || n > sizeof mem - o) return Status::out_of_range;
    std::memset(mem + o, 0xFF, n);
    return Status::ok;
  }
  std::uint8_t mem[2048];
};

using Store = fw::nvm::RecordStore<Persisted, App::kPersistedTag, MemNvm>;

Persisted g_image;

bool finite(const Core::Output& o) {
  return std::isfinite(o.r_film_est_ohm_m2) && std::isfinite(o.li_loss_ah) && std::isfinite(o.z_v) &&
         std::isfinite(o.theta[0]) && std::isfinite(o.theta[1]) && std::isfinite(o.model_voltage_v);
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
  static Model model, plant;
  model.init_default();
  plant.init_default();
  static Core core(fw::paper_cell_config<Core>(fw::Profile::best), model);
  for (int k = 0; k < 400; ++k) {
    const double i_a = k < 200 ? 2.5 : -2.5;
    const auto p = plant.step_current(i_a, fw::PaperCellTraits::kInitialFilmOhmM2, 0.2);
    core.tick({p.voltage_v, i_a, true});
  }
  g_image.core = core.save();
  g_image.tick = 400;
  g_image.budget_credit_ticks = 1000;
  return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  if (size < 5) return 0;
  static Persisted patched, out;
  patched = g_image;
  auto* bytes = reinterpret_cast<std::uint8_t*>(&patched);
  for (std::size_t i = 5; i + 10 <= size; i += 10) {
    const std::size_t at = static_cast<std::size_t>(data[i] | (data[i + 1] << 8)) % (sizeof patched - 7u);
    std::memcpy(bytes + at, data + i + 2, 8);
  }
  std::uint32_t tag = App::kPersistedTag;
  if ((data[0] & 2u) != 0u) std::memcpy(&tag, data + 1, 4);
  static MemNvm nvm;
  std::memset(nvm.mem, 0xFF, sizeof nvm.mem);
  static std::uint8_t rec[Store::kRecordBytes];
  Store probe(nvm, 0);
  if ((data[0] & 1u) != 0u) {
    fw::nvm::encode_record(&g_image, sizeof g_image, App::kPersistedTag, 1u, rec, sizeof rec);
    nvm.write(probe.slot_offset(0), rec, sizeof rec);
  }
  fw::nvm::encode_record(&patched, sizeof patched, tag, 2u, rec, sizeof rec);
  nvm.write(probe.slot_offset(1), rec, sizeof rec);

  Store store(nvm, 0);
  const fw::nvm::StoreStatus s = store.load(out);
  if (s != fw::nvm::StoreStatus::ok) return 0;
  const bool from_patched = store.newest_slot() == 1;
  if (from_patched && tag != App::kPersistedTag) fail();

  Model model, model_fresh;
  model.init_default();
  model_fresh.init_default();
  Core core(fw::paper_cell_config<Core>(fw::Profile::best), model);
  Core fresh(fw::paper_cell_config<Core>(fw::Profile::best), model_fresh);
  const bool accepted = core.restore(out.core);
  const fw::TickInput<double> inputs[] = {{3.3, 0.0, true}, {3.45, -2.5, true}, {0.0, 0.0, false}, {3.46, -2.5, true}};
  for (const auto& in : inputs) {
    const auto o = core.tick(in);
    if (accepted && !finite(o)) fail();
    if (!accepted) {
      const auto f = fresh.tick(in);
      if (std::memcmp(&o.r_film_est_ohm_m2, &f.r_film_est_ohm_m2, sizeof(double)) != 0) fail();
    }
  }
  return 0;
}
