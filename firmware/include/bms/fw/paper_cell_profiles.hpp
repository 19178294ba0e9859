#pragma once
// The estimator profiles of the paper cell as named configurations, one source for every
// caller (bms-firmware, the board image, `bmssim estimate --settings`, hil):
//   paper - the paper's RCSI (n_c = 1, eta = 0, P(0) = 5e-7 I, H = 0.01);
//   best  - BmsCore::best_config with the nominal cell's inventory, initial film and Ramadass
//           constant and the reduced model's design-time bias: nothing of the cell in use.
#include "bms/fw/bms_core.hpp"
#include "bms/fw/reduced_cell.hpp"
#include "bms/fw/reduced_model_bias.hpp"

namespace bms::fw {

enum class Profile { paper, best };

template <class Core>
typename Core::Config paper_cell_config(Profile profile) {
  using Scalar = decltype(Core::Config::dt_s);
  using Model = ReducedCell<Scalar>;
  using Cell = PaperCellTraits;
  if (profile == Profile::paper) return typename Core::Config{};
  return Core::best_config(Model::inventory_of(Scalar(Cell::kNeg.stoich_init), Scalar(Cell::kPos.stoich_init)),
                           Scalar(Cell::kInitialFilmOhmM2), Scalar(Model::nominal_film_growth_ohm_m2_per_a_m3_s()),
                           Scalar(kPaperReducedModelBiasOhm));
}

}  // namespace bms::fw
