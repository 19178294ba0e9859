#pragma once
// Open-circuit capacity of a cell from its cyclable lithium: the charge between the upper and
// the lower voltage limit at equilibrium (the contract's capacity_*_ah). At each limit the two
// electrodes share the inventory n = x C_n + y C_p (C = the electrode's solid capacity in mol,
// x, y its stoichiometries) and U_p(y) - U_n(x) = V; the capacity is C_n (x(V_max) - x(V_min)) F.
// U_p(y(x)) - U_n(x) rises monotonically with x (more lithium in the anode, less in the
// cathode), so each limit is one bisection on x over the stoichiometries both electrodes allow.
// Used by the firmware (its estimated inventory, the nominal electrode capacities and OCPs) and
// by the truth (its own inventory): the same definition on both sides.
//
// Firmware rules: no heap, fixed iteration count, no exceptions; a case without a solution
// (the inventory cannot reach one of the limits) returns NaN.
#include <cmath>
#include <limits>

#include "bms/fw/model/physical_constants.hpp"

namespace bms::fw {

// Stoichiometry of the anode at which the resting cell holding `inventory_mol` shows `voltage_v`,
// NaN when no admissible pair exists.
template <typename Scalar, typename OcpNeg, typename OcpPos>
Scalar equilibrium_stoich_neg(Scalar inventory_mol, Scalar cap_neg_mol, Scalar cap_pos_mol, Scalar voltage_v,
                              const OcpNeg& ocp_neg_v, const OcpPos& ocp_pos_v) {
  constexpr int kIterations = std::numeric_limits<Scalar>::digits;  // the interval to the last bit
  const Scalar edge = Scalar(1e-6);
  Scalar lo = (inventory_mol - cap_pos_mol * (Scalar(1) - edge)) / cap_neg_mol;
  Scalar hi = (inventory_mol - cap_pos_mol * edge) / cap_neg_mol;
  if (lo < edge) lo = edge;
  if (hi > Scalar(1) - edge) hi = Scalar(1) - edge;
  if (!(lo < hi)) return std::numeric_limits<Scalar>::quiet_NaN();
  auto excess = [&](Scalar x) {
    const Scalar y = (inventory_mol - x * cap_neg_mol) / cap_pos_mol;
    return ocp_pos_v(y) - ocp_neg_v(x) - voltage_v;
  };
  if (!(excess(lo) <= Scalar(0) && excess(hi) >= Scalar(0))) return std::numeric_limits<Scalar>::quiet_NaN();
  for (int i = 0; i < kIterations; ++i) {
    const Scalar mid = Scalar(0.5) * (lo + hi);
    if (excess(mid) < Scalar(0)) {
      lo = mid;
    } else {
      hi = mid;
    }
  }
  return Scalar(0.5) * (lo + hi);
}

// Open-circuit capacity [Ah] between v_min and v_max; NaN when either limit is out of reach.
template <typename Scalar, typename OcpNeg, typename OcpPos>
Scalar open_circuit_capacity_ah(Scalar inventory_mol, Scalar cap_neg_mol, Scalar cap_pos_mol, Scalar v_min,
                                Scalar v_max, const OcpNeg& ocp_neg_v, const OcpPos& ocp_pos_v) {
  const Scalar x_full = equilibrium_stoich_neg(inventory_mol, cap_neg_mol, cap_pos_mol, v_max, ocp_neg_v, ocp_pos_v);
  const Scalar x_empty = equilibrium_stoich_neg(inventory_mol, cap_neg_mol, cap_pos_mol, v_min, ocp_neg_v, ocp_pos_v);
  return (x_full - x_empty) * cap_neg_mol * Scalar(kFaradayC_mol / 3600.0);
}

}  // namespace bms::fw
