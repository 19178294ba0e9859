#pragma once
// Compiled replacements for the serial N_Vector operations IDA calls on every step.
// Debian 12's SUNDIALS 6.4 libraries are built without optimisation (every loop goes through
// memory): their vector operations were 64 % of a paper 1C discharge. These do the same
// arithmetic in the same order (the same special cases of N_VLinearSum, the same summation
// order in the norms, no FMA contraction), so the solver's results are unchanged bit for bit.
#include <sundials/sundials_matrix.h>
#include <sundials/sundials_nvector.h>

namespace bms {

// Installs the replacements in v's operation table; vectors IDA clones from v inherit them.
void use_fast_serial_ops(N_Vector v);
// The same for the sparse matrix's SUNMatZero, which IDA calls before every Jacobian.
void use_fast_sparse_zero(SUNMatrix m);

}  // namespace bms
