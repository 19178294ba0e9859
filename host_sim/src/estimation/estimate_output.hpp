#pragma once
// Writes estimates.csv and summary.json (contract: estimate; also used by hil).
#include <filesystem>

#include <nlohmann/json.hpp>

#include "estimation/estimate_run.hpp"
#include "estimation/film_bound.hpp"

namespace bms {

// Without a truth (a measured file) the error column inventory_err_pct is left out.
void write_estimates_csv(const std::filesystem::path& file, const EstimateResult& r, bool with_truth = true);
nlohmann::json estimate_summary_json(const EstimateResult& r, const EstimateOptions& o);
// The Cramer-Rao bound of the best profile's joint unknowns as summary.json's "crlb" (and the
// blind study's): gain, initial film, inventory, the film per cycle, the growth growth_err_pct scores.
nlohmann::json film_bound_json(const FilmBound& b);
// The design-time bias tables (null when off): the nominal level's knots at the top (abscissa,
// x_first, x_last, ohm, trusted_last) and, where it has them, every level with its inventory.
nlohmann::json model_bias_tables_json(const fw::ModelBiasTables<double>& t);

}  // namespace bms
