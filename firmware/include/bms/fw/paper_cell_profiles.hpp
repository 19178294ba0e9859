#pragma once
// The estimator profiles of the paper cell as named configurations, each make_config over the
// paper cell's nominal numbers (paper_nominal_cell): one source for every caller (bms-firmware,
// the board image, `bmssim estimate --settings`, hil). A profile is only a Config: the tick
// switches each part on by its Config fields, never by a profile's name.
//   paper        - the paper's RCSI (n_c = 1, eta = 0, P(0) = 5e-7 I, H = 0.01): BmsCore::paper_config;
//   best         - BmsCore::best_config with the nominal cell's inventory, initial film and Ramadass
//                  constant and the reduced model's design-time bias: nothing of the cell in use;
//   beyond_paper - session 5's profile, BmsCore::beyond_paper_config with the nominal cell's
//                  inventory and Ramadass constant (`bmssim estimate --beyond-paper`).
#include "bms/fw/make_config.hpp"

namespace bms::fw {

template <class Core>
typename Core::Config paper_cell_paper_config() {
  return make_config<Core>(paper_nominal_cell<decltype(Core::Config::dt_s)>(), Profile::paper);
}

template <class Core>
typename Core::Config paper_cell_best_config() {
  return make_config<Core>(paper_nominal_cell<decltype(Core::Config::dt_s)>(), Profile::best);
}

template <class Core>
typename Core::Config paper_cell_beyond_paper_config() {
  return make_beyond_paper_config<Core>(paper_nominal_cell<decltype(Core::Config::dt_s)>());
}

template <class Core>
typename Core::Config paper_cell_config(Profile profile) {
  return make_config<Core>(paper_nominal_cell<decltype(Core::Config::dt_s)>(), profile);
}

}  // namespace bms::fw
