#pragma once
// Open-circuit capacity of a cell from its cyclable lithium: the charge the resting cell holds
// between its lower and its upper end (the contract's capacity_*_ah). At each end the two
// electrodes share the inventory n = x C_n + y C_p (C = the electrode's solid capacity in mol,
// x, y its stoichiometries); the capacity is C_n (x_full - x_empty) F.
// U_p(y(x)) - U_n(x) rises monotonically with x (more lithium in the anode, less in the
// cathode), so each end is one bisection on x over the stoichiometries both electrodes allow.
//
// Each end is the voltage limit at equilibrium or an electrode's own limit, whichever the cell
// reaches first: the upper end is where U_p - U_n = V_max, or, when the anode is full (or the
// cathode empty) before the resting cell shows V_max, that full electrode; the lower end the
// same way with V_min. Why: with a little more lithium than nominal (the paper cell from an
// inventory about 0.85 % above nominal) the anode is full below 3.6 V at equilibrium, so "the
// charge between the voltage limits" had no upper end and the capacity was undefined exactly
// where a cell is healthiest; the charge such a cell can really hold ends where its anode is
// full (beyond it a charge would plate lithium, not store it). Where both limits are reached
// (every nominal cell) the two definitions are the same number. The capacity is continuous in
// the inventory across the change of end and falls again past it (the extra lithium then only
// shortens the discharge).
//
// Used by the firmware (its estimated inventory, the nominal electrode capacities and OCPs) and
// by the truth (its own inventory): the same definition on both sides.
//
// Firmware rules: no heap, fixed iteration count, no exceptions; an inventory no pair of
// stoichiometries can hold (below 0 or above C_n + C_p) returns NaN.
#include <cmath>
#include <limits>

#include "bms/fw/model/physical_constants.hpp"

namespace bms::fw {

// The anode stoichiometries [lo, hi] an inventory admits with both electrodes inside (1e-6 from
// either end); false when there are none.
template <typename Scalar>
bool admissible_stoich_neg(Scalar inventory_mol, Scalar cap_neg_mol, Scalar cap_pos_mol, Scalar& lo, Scalar& hi) {
  const Scalar edge = Scalar(1e-6);
  lo = (inventory_mol - cap_pos_mol * (Scalar(1) - edge)) / cap_neg_mol;
  hi = (inventory_mol - cap_pos_mol * edge) / cap_neg_mol;
  if (lo < edge) lo = edge;
  if (hi > Scalar(1) - edge) hi = Scalar(1) - edge;
  return lo < hi;
}

// Stoichiometry of the anode at which the resting cell holding `inventory_mol` shows `voltage_v`,
// NaN when no admissible pair exists.
template <typename Scalar, typename OcpNeg, typename OcpPos>
Scalar equilibrium_stoich_neg(Scalar inventory_mol, Scalar cap_neg_mol, Scalar cap_pos_mol, Scalar voltage_v,
                              const OcpNeg& ocp_neg_v, const OcpPos& ocp_pos_v) {
  constexpr int kIterations = std::numeric_limits<Scalar>::digits;  // the interval to the last bit
  Scalar lo = Scalar(0);
  Scalar hi = Scalar(0);
  if (!admissible_stoich_neg(inventory_mol, cap_neg_mol, cap_pos_mol, lo, hi))
    return std::numeric_limits<Scalar>::quiet_NaN();
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

// The anode's stoichiometry at one end of the capacity window: where the resting cell holding
// `inventory_mol` shows `voltage_v`, or the end of the admissible range the cell reaches first
// (an electrode full or empty before that voltage: see the header). NaN when no admissible pair
// exists.
template <typename Scalar, typename OcpNeg, typename OcpPos>
Scalar window_end_stoich_neg(Scalar inventory_mol, Scalar cap_neg_mol, Scalar cap_pos_mol, Scalar voltage_v,
                             const OcpNeg& ocp_neg_v, const OcpPos& ocp_pos_v) {
  Scalar lo = Scalar(0);
  Scalar hi = Scalar(0);
  if (!admissible_stoich_neg(inventory_mol, cap_neg_mol, cap_pos_mol, lo, hi))
    return std::numeric_limits<Scalar>::quiet_NaN();
  const Scalar y_lo = (inventory_mol - lo * cap_neg_mol) / cap_pos_mol;
  const Scalar y_hi = (inventory_mol - hi * cap_neg_mol) / cap_pos_mol;
  const Scalar at_lo = ocp_pos_v(y_lo) - ocp_neg_v(lo) - voltage_v;
  const Scalar at_hi = ocp_pos_v(y_hi) - ocp_neg_v(hi) - voltage_v;
  if (!std::isfinite(at_lo) || !std::isfinite(at_hi)) return std::numeric_limits<Scalar>::quiet_NaN();
  if (at_lo > Scalar(0)) return lo;  // above the voltage even at its emptiest: that end is the electrode's
  if (at_hi < Scalar(0)) return hi;  // below it even at its fullest (the anode full first)
  return equilibrium_stoich_neg(inventory_mol, cap_neg_mol, cap_pos_mol, voltage_v, ocp_neg_v, ocp_pos_v);
}

// Open-circuit capacity [Ah] between the lower and the upper end (v_min, v_max or an electrode's
// limit, whichever comes first); NaN only for an inventory no electrode pair can hold.
template <typename Scalar, typename OcpNeg, typename OcpPos>
Scalar open_circuit_capacity_ah(Scalar inventory_mol, Scalar cap_neg_mol, Scalar cap_pos_mol, Scalar v_min,
                                Scalar v_max, const OcpNeg& ocp_neg_v, const OcpPos& ocp_pos_v) {
  const Scalar x_full = window_end_stoich_neg(inventory_mol, cap_neg_mol, cap_pos_mol, v_max, ocp_neg_v, ocp_pos_v);
  const Scalar x_empty = window_end_stoich_neg(inventory_mol, cap_neg_mol, cap_pos_mol, v_min, ocp_neg_v, ocp_pos_v);
  return (x_full - x_empty) * cap_neg_mol * Scalar(kFaradayC_mol / 3600.0);
}

}  // namespace bms::fw
