#include "estimation/estimate_output.hpp"

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

#include "io/csv_table.hpp"

namespace bms {

namespace {
nlohmann::json finite_or_null(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }

nlohmann::json bias_level_json(const fw::ModelBiasTable<double>& t) {
  return {{"x_first", t.x_first}, {"x_last", t.x_last}, {"ohm", t.ohm}, {"trusted_last", finite_or_null(t.x_trusted_last)}};
}

// The configuration that ran (keys as before), only what the profile uses: RCSI's settings
// where RCSI learns, the identifier's where it does, the observer's where it runs.
nlohmann::json options_json(const EstimateConfigSummary& c, const EstimateOptions& o) {
  nlohmann::json j = {{"model", o.model}, {"settings", fw::profile_name(o.profile)}, {"learning", c.learning},
                      {"identify_growth", c.identify_growth}, {"h_from_model", c.h_from_model}, {"delay", 0},
                      {"resync", c.resync_at_cv_end}, {"warmup_s", c.warmup_s},
                      {"voltage_window_v", {c.voltage_min_v, c.voltage_max_v}},
                      {"model_ic", {{"stoich_neg", o.ic.stoich_neg}, {"stoich_pos", o.ic.stoich_pos},
                                    {"electrolyte_mol_m3", o.ic.electrolyte_mol_m3}}}};
  if (!c.filled) return j;
  if (c.identify_growth) {
    j["learn_inventory"] = c.learn_inventory;
    j["model_bias_ohm"] = c.model_bias_ohm;
    j["model_bias_table"] = model_bias_tables_json(c.model_bias_table);
    const double span_end = c.model_bias_table.nominal().x_trusted_last;
    j["trusted_span_end"] = std::isfinite(span_end) ? nlohmann::json(span_end) : nlohmann::json(nullptr);
    j["stated_spread_rel"] = {{"anode_i0", c.spread.anode_i0_rel}, {"cathode_i0", c.spread.cathode_i0_rel},
                              {"transport", c.spread.transport_rel}, {"area", c.spread.area_rel}};
    j["fuse_level_only"] = c.fuse_level_only;
    j["stated_film_initial_sd_rel"] = c.film_initial_sd_rel;
    j["voltage_offset_sd_mv"] = c.voltage_offset_sd_v * 1e3;
    j["current_gain_sd_pct"] = c.current_gain_sd * 1e2;
    j["voltage_offset"] = c.voltage_offset;
    if (c.resync_at_cv_end) j["relinearise_inventory"] = c.relinearise_inventory;
  } else {
    j.update({{"nc", c.nc}, {"p0", c.p0_u}, {"p0_y0", c.p0_y0}, {"lambda", c.lambda}, {"eta", c.eta},
              {"calibrate_bias", c.calibrate_bias}, {"average_estimate", c.average_estimate},
              {"propagate_growth", c.propagated_growth_ohm_m2_per_a_m3_s != 0.0}});
    if (!c.h_from_model) j["h"] = c.h_v_per_ohm_m2;
    if (c.calibrate_bias && c.resync_at_cv_end) j["reference_after_resyncs"] = c.reference_after_resyncs;
    if (c.propagated_growth_ohm_m2_per_a_m3_s != 0.0)
      j["propagated_growth_ohm_m2_per_a_m3_s"] = c.propagated_growth_ohm_m2_per_a_m3_s;
  }
  if (c.resync_at_cv_end)
    j.update({{"resync_at_start", c.resync_at_start}, {"resync_window_ticks", c.resync_window_ticks},
              {"resync_settle_s", c.resync_settle_s},
              {"resync_current_a", c.resync_current_a}, {"inventory_error_pct", o.inventory_error_pct.or_else(0.0)}});
  return j;
}
}  // namespace

void write_estimates_csv(const std::filesystem::path& file, const EstimateResult& r, bool with_truth) {
  std::vector<std::string> cols = {"t_s", "cycle", "mode", "rcsi_active", "r_film_est_ohm_m2", "r_film_true_ohm_m2",
                                   "z_v", "model_voltage_v", "model_current_a", "j_side_a_m3", "li_loss_ah", "status",
                                   "film_initial_est_ohm_m2", "growth_gain_est", "inventory_deviation_est"};
  if (with_truth) cols.push_back("inventory_err_pct");
  for (const char* c : {"r_film_sd_ohm_m2", "capacity_est_ah", "capacity_sd_ah", "capacity_true_ah",
                        "innovation_test_ratio", "current_offset_est_a", "model_bias_v"})
    cols.push_back(c);
  const std::size_t n_theta = r.theta.size();
  for (std::size_t i = 0; i < n_theta / 2; ++i) cols.push_back("theta_m" + std::to_string(i + 1));
  for (std::size_t i = 0; i < n_theta / 2; ++i) cols.push_back("theta_n" + std::to_string(i + 1));
  CsvWriter w(file, cols);
  for (std::size_t i = 0; i < r.rows.size(); ++i) {
    const auto& row = r.rows[i];
    w.cell(row.t_s).cell(row.cycle).cell(fw::mode_name(row.mode)).cell(row.rcsi_active ? 1 : 0);
    w.cell(row.r_film_est_ohm_m2);
    if (std::isfinite(row.r_film_true_ohm_m2)) w.cell(row.r_film_true_ohm_m2);
    else w.cell("");
    w.cell(row.z_v).cell(row.model_voltage_v).cell(row.model_current_a).cell(row.j_side_a_m3).cell(row.li_loss_ah);
    w.cell(row.status).cell(row.film_initial_ohm_m2).cell(row.growth_gain).cell(row.inventory_deviation);
    if (with_truth) {
      if (std::isfinite(row.inventory_err_pct)) w.cell(row.inventory_err_pct);
      else w.cell("");
    }
    for (double v : {row.r_film_sd_ohm_m2, row.capacity_est_ah, row.capacity_sd_ah, row.capacity_true_ah,
                     row.innovation_test_ratio, row.current_offset_a, row.model_bias_v}) {
      if (std::isfinite(v)) w.cell(v);
      else w.cell("");
    }
    for (double th : r.theta_rows[i]) w.cell(th);
    w.end_row();
  }
  w.commit();
}

nlohmann::json estimate_summary_json(const EstimateResult& r, const EstimateOptions& o) {
  nlohmann::json j;
  j["cycles"] = nlohmann::json::array();
  for (const auto& c : r.cycles) {
    j["cycles"].push_back({{"cycle", c.cycle},
                           {"r_film_err_median_pct", c.r_film_err_median_pct},
                           {"r_film_err_end_pct", c.r_film_err_end_pct},
                           {"r_film_true_end_ohm_m2", c.r_film_true_end_ohm_m2},
                           {"r_film_est_end_ohm_m2", c.r_film_est_end_ohm_m2},
                           {"cc_charge_ticks", c.cc_charge_ticks},
                           {"inventory_err_end_pct", finite_or_null(c.inventory_err_end_pct)},
                           {"capacity_err_pct", finite_or_null(c.capacity_err_pct)},
                           {"film_within_2sd_pct", finite_or_null(c.film_within_2sd_pct)},
                           {"misfit_pct", c.misfit_pct}});
  }
  j["theta"] = r.theta;
  j["growth_err_pct"] = finite_or_null(r.growth_err_pct);
  if (o.profile == fw::Profile::best && !r.rows.empty()) {
    const auto& last = r.rows.back();
    j["identified"] = {{"film_initial_ohm_m2", last.film_initial_ohm_m2},
                       {"growth_gain", last.growth_gain},
                       {"inventory_deviation", last.inventory_deviation}};
  }
  if (!r.rows.empty()) j["current_offset_a"] = r.rows.back().current_offset_a;
  if (!r.rows.empty() && r.config.voltage_offset) j["voltage_offset_v"] = r.rows.back().voltage_offset_v;
  if (!r.rows.empty()) j["area_scale"] = r.rows.back().area_scale;
  j["status_bits_seen"] = r.status;
  j["newton_cap_hits"] = r.newton_cap_hits;
  j["wall_s"] = r.wall_s;
  j["ticks"] = r.rows.size();
  j["options"] = options_json(r.config, o);
  return j;
}

nlohmann::json model_bias_tables_json(const fw::ModelBiasTables<double>& t) {
  if (!t.on()) return nullptr;
  nlohmann::json j = bias_level_json(t.nominal());
  j["abscissa"] = "the model's mean anode stoichiometry";
  if (!t.by_inventory()) return j;
  j["inventory_step"] = t.nu_step;
  j["levels"] = nlohmann::json::array();
  for (int k = 0; k < fw::kModelBiasLevels; ++k) {
    nlohmann::json l = bias_level_json(t.level[k]);
    l["inventory_deviation"] = (k - fw::ModelBiasTables<double>::kNominal) * t.nu_step;
    j["levels"].push_back(l);
  }
  return j;
}

nlohmann::json film_bound_json(const FilmBound& b) {
  nlohmann::json j;
  j["valid"] = b.valid;
  j["gain_sd"] = finite_or_null(b.gain_sd);
  j["r0_sd_ohm_m2"] = finite_or_null(b.r0_sd_ohm_m2);
  j["inventory_sd_pct"] = finite_or_null(b.inventory_sd_pct);
  nlohmann::json by = nlohmann::json::array();
  double worst = 0.0;
  for (const auto& c : b.cycles) {
    by.push_back(finite_or_null(c.film_sd_pct));
    if (c.cycle >= 3 && std::isfinite(c.film_sd_pct)) worst = std::max(worst, c.film_sd_pct);
  }
  j["film_sd_pct_by_cycle"] = by;
  j["film_sd_pct_worst_cycles_3_on"] = worst;
  j["growth_sd_ohm_m2"] = finite_or_null(b.growth_sd_ohm_m2);
  j["growth_sd_pct"] = finite_or_null(b.growth_sd_pct);
  return j;
}

}  // namespace bms
