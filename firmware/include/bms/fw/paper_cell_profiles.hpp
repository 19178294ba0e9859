#pragma once
// The estimator profiles of the paper cell as named configurations, one source for every
// caller (bms-firmware, the board image, `bmssim estimate --settings`, hil). A profile is only a
// Config: the tick switches each part on by its Config fields, never by a profile's name.
//   paper        - the paper's RCSI (n_c = 1, eta = 0, P(0) = 5e-7 I, H = 0.01): BmsCore::paper_config;
//   best         - BmsCore::best_config with the nominal cell's inventory, initial film and Ramadass
//                  constant and the reduced model's design-time bias: nothing of the cell in use;
//   beyond_paper - session 5's profile, BmsCore::beyond_paper_config with the nominal cell's
//                  inventory and Ramadass constant (`bmssim estimate --beyond-paper`).
#include "bms/fw/bms_core.hpp"
#include "bms/fw/reduced_cell.hpp"
#include "bms/fw/reduced_model_bias.hpp"

namespace bms::fw {

enum class Profile { paper, best };

template <class Core>
typename Core::Config paper_cell_paper_config() {
  return Core::paper_config();
}

template <class Core>
typename Core::Config paper_cell_best_config() {
  using Scalar = decltype(Core::Config::dt_s);
  using Model = ReducedCell<Scalar>;
  using Cell = PaperCellTraits;
  return Core::best_config(Model::inventory_of(Scalar(Cell::kNeg.stoich_init), Scalar(Cell::kPos.stoich_init)),
                           Scalar(Cell::kInitialFilmOhmM2), Scalar(Model::nominal_film_growth_ohm_m2_per_a_m3_s()),
                           Scalar(kPaperReducedModelBiasOhm));
}

template <class Core>
typename Core::Config paper_cell_beyond_paper_config() {
  using Scalar = decltype(Core::Config::dt_s);
  using Model = ReducedCell<Scalar>;
  using Cell = PaperCellTraits;
  return Core::beyond_paper_config(Model::inventory_of(Scalar(Cell::kNeg.stoich_init), Scalar(Cell::kPos.stoich_init)),
                                   Scalar(Model::nominal_film_growth_ohm_m2_per_a_m3_s()));
}

template <class Core>
typename Core::Config paper_cell_config(Profile profile) {
  return profile == Profile::paper ? paper_cell_paper_config<Core>() : paper_cell_best_config<Core>();
}

}  // namespace bms::fw
