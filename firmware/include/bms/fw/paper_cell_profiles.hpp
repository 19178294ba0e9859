#pragma once
// The estimator profiles of the paper cell (make_config.hpp over paper_nominal_cell): the
// nominal cell's inventory, initial film and Ramadass constant and the reduced model's
// design-time bias, nothing of the cell in use.
#include "bms/fw/make_config.hpp"

namespace bms::fw {

template <class Core>
typename Core::Config paper_cell_config(Profile profile) {
  using Scalar = decltype(Core::Config::dt_s);
  return make_config<Core>(paper_nominal_cell<Scalar>(), profile);
}

}  // namespace bms::fw
