#pragma once
// One place that turns what a BMS knows of its cell (the nominal numbers of the data sheet and
// of the model's design, never the cell in use) and an estimator profile into BmsCore's
// Config. Every caller builds its configuration here: bms-firmware, the board image,
// `bmssim estimate` and `bmssim hil` (through bms-firmware's --settings).
//   paper - the paper's RCSI (n_c = 1, eta = 0, P(0) = 5e-7 I, H = 0.01);
//   best  - BmsCore::best_config: film, growth gain and lithium inventory identified together.
#include "bms/fw/bms_core.hpp"
#include "bms/fw/reduced_cell.hpp"
#include "bms/fw/reduced_model_bias.hpp"

namespace bms::fw {

enum class Profile { paper, best };

/// The nominal cell as the firmware knows it.
struct NominalCell {
  double inventory_mol;                     ///< cyclable lithium of the nominal cell
  double initial_film_ohm_m2;               ///< film resistance at the start of life
  double growth_ohm_m2_per_a_m3_s;          ///< nominal Ramadass constant per side current
  double model_bias_ohm;                    ///< the reduced model's design-time film bias
  double lower_voltage_v;                   ///< the cell's voltage window
  double upper_voltage_v;
};

/// Margin of the measured-voltage plausibility check outside the cell's window: a sensor
/// reading of 0 V (what a NaN becomes on the bus) is rejected, not modelled.
inline constexpr double kVoltagePlausibilityMarginV = 0.5;

/// The paper's cell (reduced_cell.hpp's PaperCellTraits) as the nominal cell.
template <class Scalar>
NominalCell paper_nominal_cell() {
  using Model = ReducedCell<Scalar>;
  using Cell = PaperCellTraits;
  return {static_cast<double>(Model::inventory_of(Scalar(Cell::kNeg.stoich_init), Scalar(Cell::kPos.stoich_init))),
          Cell::kInitialFilmOhmM2,
          static_cast<double>(Model::nominal_film_growth_ohm_m2_per_a_m3_s()),
          kPaperReducedModelBiasOhm,
          Cell::kLowerVoltageV,
          Cell::kUpperVoltageV};
}

/// The cell's voltage window in the mode detector and the plausibility check.
template <class Config>
void apply_voltage_window(const NominalCell& cell, Config& cfg) {
  using Scalar = decltype(Config::dt_s);
  cfg.detector.v_min = Scalar(cell.lower_voltage_v);
  cfg.detector.v_max = Scalar(cell.upper_voltage_v);
  cfg.voltage_min_v = Scalar(cell.lower_voltage_v - kVoltagePlausibilityMarginV);
  cfg.voltage_max_v = Scalar(cell.upper_voltage_v + kVoltagePlausibilityMarginV);
}

template <class Core>
typename Core::Config make_config(const NominalCell& cell, Profile profile) {
  using Scalar = decltype(Core::Config::dt_s);
  typename Core::Config cfg =
      profile == Profile::paper
          ? Core::paper_config()
          : Core::best_config(Scalar(cell.inventory_mol), Scalar(cell.initial_film_ohm_m2),
                              Scalar(cell.growth_ohm_m2_per_a_m3_s), Scalar(cell.model_bias_ohm));
  apply_voltage_window(cell, cfg);
  return cfg;
}

/// Session 5's profile (`--beyond-paper`): it assumes the nominal growth law (documented in
/// docs/results/firmware-model.md); kept for comparison.
template <class Core>
typename Core::Config make_beyond_paper_config(const NominalCell& cell) {
  using Scalar = decltype(Core::Config::dt_s);
  typename Core::Config cfg =
      Core::beyond_paper_config(Scalar(cell.inventory_mol), Scalar(cell.growth_ohm_m2_per_a_m3_s));
  apply_voltage_window(cell, cfg);
  return cfg;
}

}  // namespace bms::fw
