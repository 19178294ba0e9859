#include "sim/cell_catalog.hpp"

#include <cstdlib>

#include "cell/paper_cell.hpp"
#include "io/bpx_reader.hpp"
#include "io/input_error.hpp"

#ifndef BMS_CELLS_DIR
#define BMS_CELLS_DIR "host_sim/cells"
#endif

#ifndef BMS_DEFAULT_SHARED_DIR
#define BMS_DEFAULT_SHARED_DIR "../shared"
#endif

namespace bms {

std::filesystem::path shared_dir() {
  if (const char* env = std::getenv("BMS_SHARED_DIR"); env && *env) return env;
  return BMS_DEFAULT_SHARED_DIR;
}

std::filesystem::path cell_template_file(const std::string& name) {
  return std::filesystem::path(BMS_CELLS_DIR) / (name + ".bpx.json");
}

CellParameters load_cell(const std::string& name_or_file) {
  if (name_or_file == "paper") return make_paper_cell();
  if (name_or_file == "aboutenergy") {
    const auto file = shared_dir() / "data/aboutenergy-lfp18650/lfp_18650_cell_BPX.json";
    if (!std::filesystem::exists(file))
      throw InputError("--cell aboutenergy: " + file.string() +
                       " not found (set BMS_SHARED_DIR to the shared/ folder)");
    CellParameters c = read_bpx(file);
    c.name = "aboutenergy";
    return c;
  }
  if (name_or_file == "lco" || name_or_file == "nmc") {
    // The project's templates (host_sim/cells/, sources in each file and docs/parameters.md).
    CellParameters c = read_bpx(cell_template_file(name_or_file));
    c.name = name_or_file;
    return c;
  }
  if (!std::filesystem::exists(name_or_file))
    throw InputError("--cell: '" + name_or_file +
                     "' is neither 'paper', 'aboutenergy', 'lco', 'nmc' nor an existing BPX file");
  return read_bpx(name_or_file);
}

}  // namespace bms
