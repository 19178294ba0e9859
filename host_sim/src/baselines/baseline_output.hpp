#pragma once
// Output of `bmssim baseline`: DIR/estimates.csv and DIR/summary.json (names fixed: `bmssim
// study` reads them).
#include <filesystem>

#include <nlohmann/json.hpp>

#include "baselines/baseline_run.hpp"

namespace bms::baselines {

// t_s,cycle,mode,r_film_est_ohm_m2,r_film_true_ohm_m2,r_film_sigma_ohm_m2,model_voltage_v,z_v
// (empty cells where a value does not exist: no estimate for the bound, no truth in the file).
void write_baseline_csv(const std::filesystem::path& file, const BaselineResult& r);

// {"method", "cycles":[{"cycle","r_film_err_median_pct","r_film_err_end_pct","crlb_rel_pct",..}],
//  "wall_s", "noise":{..}, "options":{..}}; the error fields are null for the bound.
nlohmann::json baseline_summary_json(const BaselineResult& r, const BaselineOptions& o);

}  // namespace bms::baselines
