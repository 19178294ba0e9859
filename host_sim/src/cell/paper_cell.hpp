#pragma once
#include "cell/cell_parameters.hpp"

namespace bms {

// The paper-reproduction parameter set, built from firmware/include/bms/fw/model/paper_cell.hpp.
CellParameters make_paper_cell();

}  // namespace bms
