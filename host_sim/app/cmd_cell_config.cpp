// `bmssim cell-config`: the firmware's cell configuration from a parameter set (the generator of
// the cell as data, cell/reduced_cell_record.hpp). Writes DIR/<name>_cell.hpp (a traits struct
// for ReducedCell, PaperCellTraits' fields plus the design-time bias and the record's CRC-32)
// and DIR/summary.json (table errors, bias, what the reduced model leaves out).
#include <cctype>
#include <cmath>
#include <cstdio>
#include <memory>
#include <string>

#include <fmt/format.h>
#include <nlohmann/json.hpp>

#include "cell/reduced_cell_record.hpp"
#include "commands.hpp"
#include "estimation/design_bias.hpp"
#include "estimation/estimate_output.hpp"
#include "sim/truth_output.hpp"
#include "io/output_folder.hpp"
#include "sim/cell_catalog.hpp"

namespace bms::app {
namespace {

struct CellConfigCli {
  std::string cell = "aboutenergy";
  std::string out;
  double bias_ohm = std::nan("");  // NaN: computed from the nominal DFN
  bool quiet = false;
};

// "aboutenergy" -> "AboutenergyCellTraits"; a file's stem with non-identifier characters dropped.
std::string type_name_for(const std::string& name) {
  std::string t;
  bool upper = true;
  for (const char ch : name) {
    if (std::isalnum(static_cast<unsigned char>(ch)) == 0) {
      upper = true;
      continue;
    }
    t += upper ? static_cast<char>(std::toupper(static_cast<unsigned char>(ch))) : ch;
    upper = false;
  }
  if (t.empty() || std::isdigit(static_cast<unsigned char>(t[0])) != 0) t = "Cell" + t;
  return t + "CellTraits";
}

// Per lower charge rate, the fit's 90th percentile (null: the nominal DFN could not run it).
nlohmann::json coverage_json(const std::vector<DesignBias::RateFit>& fits) {
  nlohmann::json j = nlohmann::json::array();
  for (const auto& f : fits)
    j.push_back({{"c_rate", f.c_rate}, {"fit_v_p90", std::isfinite(f.fit_p90_v) ? nlohmann::json(f.fit_p90_v) : nlohmann::json(nullptr)}});
  return j;
}

int run_cell_config(const CellConfigCli& c) {
  const CellParameters cell = load_cell(c.cell);
  const ReducedCellRecord record = make_reduced_cell_record(cell);
  OutputFolder folder(c.out);
  DesignBias bias;
  if (std::isfinite(c.bias_ohm)) {
    bias.bias_ohm = c.bias_ohm;
  } else {
    if (!c.quiet) std::fprintf(stderr, "cell-config: design-time bias of '%s' (nominal DFN, 3 cycles)...\n", cell.name.c_str());
    bias = design_time_bias(cell);
  }
  const std::string type = type_name_for(cell.name);
  const std::string header = fmt::format("{}_cell.hpp", cell.name);
  write_file_atomically(folder.staging() / header, cell_header_text(record, type, bias.bias_ohm, bias.table));
  const nlohmann::json j = {
      {"cell", cell.name},
      {"source", cell.source},
      {"header", header},
      {"traits", "bms::fw::cells::" + type},
      {"record_crc32", fmt::format("0x{:08X}", record_crc32(record, bias.bias_ohm, bias.table))},
      {"model_bias_ohm", bias.bias_ohm},
      {"model_bias_from", std::isfinite(c.bias_ohm) ? "--model-bias-ohm" : "nominal DFN, 3 CCCV cycles at 1C (CV to C/10), 40/40 volumes, rtol 1e-9; the table also at the inventory 1 % below and above nominal"},
      {"model_bias_ticks", bias.ticks},
      {"model_bias_table", model_bias_tables_json(bias.table)},
      {"model_bias_level_notes", bias.level_notes},
      {"coverage_covered_charge_a_min", bias.table.covered_charge_a_min},
      {"coverage_constant_alone_covered", bias.table.constant_alone_covered},
      {"coverage_constant_alone_fit_v_p90", bias.constant_alone_fit_p90_v},
      {"coverage_fit_v_p90_by_c_rate", coverage_json(bias.coverage)},
      {"knot_misfit_v_p90", bias.table.on() ? nlohmann::json(bias.knot_misfit_v) : nlohmann::json(nullptr)},
      {"nominal_residual_constant_v_p10_p50_p90", bias.residual_constant_v},
      {"nominal_residual_table_v_p10_p50_p90", bias.residual_table_v},
      {"ocp_table_nodes", kOcpTableNodes},
      {"electrolyte_table_nodes", kElectrolyteTableNodes},
      {"ocp_neg_max_err_v", record.ocp_neg_max_err_v},
      {"ocp_pos_max_err_v", record.ocp_pos_max_err_v},
      {"diffusivity_max_rel_err", record.diffusivity_max_rel_err},
      {"conductivity_max_rel_err", record.conductivity_max_rel_err},
      {"side_reaction", cell.side.source},
      {"left_out", record.notes},
      {"wall_s", bias.wall_s}};
  write_file_atomically(folder.staging() / "summary.json", j.dump(2) + "\n");
  folder.commit();
  if (!c.quiet)
    std::printf("%s: %s, bias %.6e ohm, OCP table error %.3g / %.3g V\n", cell.name.c_str(),
                (folder.destination() / header).c_str(), bias.bias_ohm, record.ocp_neg_max_err_v,
                record.ocp_pos_max_err_v);
  return 0;
}

}  // namespace

Runner add_cell_config(CLI::App& app) {
  auto* sub = app.add_subcommand(
      "cell-config",
      "Generate the firmware's cell configuration (a C++ traits header for the reduced model: OCP and "
      "electrolyte tables with their errors, the side reaction's constants, the design-time model bias) from a "
      "parameter set");
  auto c = std::make_shared<CellConfigCli>();
  sub->add_option("--cell", c->cell, "paper | aboutenergy | lco | nmc | FILE.bpx.json")->capture_default_str();
  sub->add_option("--out", c->out, "Output folder (<name>_cell.hpp, summary.json)")->required();
  sub->add_option("--model-bias-ohm", c->bias_ohm,
                  "Use this design-time bias (ohm, any sign) instead of computing it from the nominal cell's DFN");
  sub->add_flag("--quiet", c->quiet, "No progress output");
  return [c]() { return run_cell_config(*c); };
}

}  // namespace bms::app
