#include "baselines/baseline_output.hpp"

#include <cmath>

#include "io/csv_table.hpp"

namespace bms::baselines {

namespace {
nlohmann::json number_or_null(double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); }
}  // namespace

void write_baseline_csv(const std::filesystem::path& file, const BaselineResult& r) {
  CsvWriter w(file, {"t_s", "cycle", "mode", "r_film_est_ohm_m2", "r_film_true_ohm_m2", "r_film_sigma_ohm_m2",
                     "model_voltage_v", "z_v"});
  auto opt = [&w](double v) -> CsvWriter& { return std::isfinite(v) ? w.cell(v) : w.cell(""); };
  for (std::size_t i = 0; i < r.rows.size(); ++i) {
    const auto& row = r.rows[i];
    w.cell(row.t_s).cell(row.cycle).cell(fw::mode_name(row.mode));
    opt(row.r_film_est_ohm_m2);
    opt(row.r_film_true_ohm_m2);
    opt(r.r_sigma_ohm_m2[i]);
    opt(row.model_voltage_v);
    opt(row.z_v);
    w.end_row();
  }
  w.commit();
}

nlohmann::json baseline_summary_json(const BaselineResult& r, const BaselineOptions& o) {
  nlohmann::json j;
  j["method"] = r.method;
  j["cycles"] = nlohmann::json::array();
  for (const auto& b : r.bounds) {
    nlohmann::json c = {{"cycle", b.cycle},
                        {"r_film_err_median_pct", nullptr},
                        {"r_film_err_end_pct", nullptr},
                        {"crlb_rel_pct", number_or_null(b.rel_pct)},
                        {"crlb_ohm_m2", number_or_null(b.bound_ohm_m2)},
                        {"cc_charge_ticks", b.ticks}};
    for (const auto& s : r.scores) {
      if (s.cycle != b.cycle) continue;
      c["r_film_err_median_pct"] = s.r_film_err_median_pct;
      c["r_film_err_end_pct"] = s.r_film_err_end_pct;
      c["r_film_true_end_ohm_m2"] = s.r_film_true_end_ohm_m2;
      c["r_film_est_end_ohm_m2"] = s.r_film_est_end_ohm_m2;
    }
    for (const auto& f : r.batch_cycles) {
      if (f.cycle != b.cycle) continue;
      c["batch"] = {{"r_a_ohm_m2", f.r_a_ohm_m2},
                    {"r_b_ohm_m2", f.r_b_ohm_m2},
                    {"sigma_a_ohm_m2", f.sigma_a_ohm_m2},
                    {"residual_rms_mv", f.rms_residual_v * 1e3},
                    {"residual_mean_mv", f.mean_residual_v * 1e3},
                    {"iterations", f.iterations}};
    }
    j["cycles"].push_back(c);
  }
  j["noise"] = {{"sigma_v_mv", r.noise.sigma_v_v * 1e3},
                {"sigma_v_source", r.noise.v_source},
                {"sigma_i_ma", r.noise.sigma_i_a * 1e3},
                {"sigma_i_source", r.noise.i_source}};
  j["wall_s"] = r.wall_s;
  j["ticks"] = r.rows.size();
  if (r.method == "ekf") {
    j["ekf_updates"] = r.ekf_updates;
    j["ekf_gated"] = r.ekf_gated;
    j["options"] = {{"q_r_ohm_m2_per_sqrt_s", o.ekf.q_r_ohm_m2_per_sqrt_s},
                    {"q_conc_rel_per_sqrt_s", o.ekf.q_conc_rel_per_sqrt_s},
                    {"p0_r_rel", o.ekf.p0_r_rel},
                    {"p0_conc_rel", o.ekf.p0_conc_rel},
                    {"gate_sigmas", o.ekf.gate_sigmas},
                    {"model_error_mv", o.ekf.model_error_v * 1e3},
                    {"update", o.ekf.update_all_cc ? "cc" : "cc_charge"}};
  } else if (r.method == "batch") {
    j["options"] = {{"shape", o.batch.linear ? "linear" : "constant"}};
  } else {
    j["options"] = nlohmann::json::object();
  }
  j["model"] = "reduced";
  return j;
}

}  // namespace bms::baselines
