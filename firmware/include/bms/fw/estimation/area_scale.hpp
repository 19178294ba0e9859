#pragma once
// The cell's electrode-capacity (area) scale a, identified from the BMS's own counted charge
// (beyond the paper; tick steps 2, 6 and 7). A cell with a times the nominal electrode area
// holds a times the lithium per stoichiometry and sees 1/a of the current density at a given
// current: it is the nominal cell driven by I / a, with its inventory in the nominal cell's
// units n / a. So the model runs on I / a (Config::model_sees) and the open-circuit capacity is
// a C_nom(n / a), both with the nominal electrodes and OCPs.
//
// Where a comes from: two CV ends (the model's state pinned by the measured voltage at the end of
// a constant-voltage phase, where the voltage is steep in the stoichiometry: the model was
// voltage-driven through the phase and is then re-synchronised) with a large charge between them
// (a full charge or discharge). Between the two pins the cell moved Q (counted, the sensor's
// measured offset removed); the model's anode, pinned at both ends, moved dA, and its side
// reaction took dL more lithium. In the nominal cell's units the anode moved -Q / a - dL, so each
// span measures a = -Q / (dA + dL). Spans are combined with weights Q^2 (the pins' error is a
// fixed amount of lithium, so a's error falls as 1 / Q) and a memory that lets later spans (the
// offset removed, the model on the updated area) count more.
//
// What the two end pins cannot do is tell a from the inventory: at the upper end the steep
// electrode is the cathode, so the pinned anode moves with the inventory one to one, and a span
// measures only the product a x (the model's window at its inventory), i.e. the capacity. So the
// capacity is a C_nom(n_span) with n_span the model's inventory over the span, not the
// identified inventory of the fit. The split between a and the inventory is the CC charge's
// voltage shape's (the identifier's inventory, with the model on I / a).
//
// Both pins of a span must see the model at one inventory, and that inventory is n_span: a
// re-synchronisation at a CV end moves the model's inventory to the fit's, so the span ends on
// the model as the voltage-driven CV phase left it (before the re-synchronisation) and the next
// span starts after it. Pinned after it at both ends (the earlier form), a span ending on a
// re-synchronisation that moved the inventory by dn read the anode's move at one inventory and
// the capacity at the other: at the upper end the anode moves with dn, so a and C_nom(n_span) each
// took dn, and a current gain, which the fit's inventory takes up, reached the capacity twice
// (measured: docs/results/envelope.md, "A current gain enters the capacity once"). For the same
// reason spans at different inventories are combined as capacities: before a span at n is
// combined, the kept scale (measured at the last span's inventory n') is carried to n by
// C_nom(n') / C_nom(n), so that a C_nom(n) keeps each span's own product.
// Measured and left out (docs/results/envelope.md, "Capacity"): a power-up pin (at rest on a flat
// OCV it pins the anode poorly: a 3-4 % off on two of six spread truths), and pinning only where
// the re-synchronisation succeeds (with the area off, the inventory takes it up, the CV-charge
// end then finds no state with an over-full anode, and no span is ever measured).
//
// A current sensor's gain g is the same as an area scale in counted charge: a reads a (1 + g),
// the model then runs on the right current density, and the capacity is reported in the
// sensor's amperes (1 + g times the cell's): once, the floor of a BMS that counts its charge.
// Header-only C++17: no heap, no exceptions, no RTTI.
#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>

#include "bms/fw/model/physical_constants.hpp"

namespace bms::fw {

template <typename Scalar>
class AreaScale {
 public:
  struct Config {
    bool enabled = false;
    // The model runs on I / a (the film path and the inventory see the area); false: only the
    // capacity is scaled (the best profile's choice: with the model on I / a the film and the
    // growth got worse on the blind sensor set, and the capacity no better there).
    bool model_sees = true;
    // The least counted charge between two pins that measures a [mol]; set from the nominal
    // cell's capacity by BmsCore (min_span_of_capacity x its open-circuit capacity).
    Scalar min_span_of_capacity = Scalar(0.5);
    Scalar min_span_mol = Scalar(0);
    Scalar limit = Scalar(0.1);   // |a - 1| admitted; a span outside is dropped
    Scalar memory = Scalar(0.5);  // weight kept of the earlier spans at each later one
    Scalar dt_s = Scalar(0.2);
  };

  // Trivially copyable, for the NVM image.
  struct State {
    Scalar scale;
    Scalar weight;          // sum of the spans' weights (with memory), mol^2
    Scalar counted_mol;     // charge counted since the last pin (positive = discharge)
    Scalar counted_carry_mol;
    Scalar pinned_anode_mol;
    Scalar pinned_loss_mol;
    Scalar span_inventory_mol;  // the model's inventory plus its loss at the end pin of the last span that measured a
    std::uint32_t flags;    // bit 0: a pin exists, bit 1: a span has measured a
  };
  static_assert(std::is_trivially_copyable<State>::value, "State must be trivially copyable");

  // The model's lithium at a pin [mol]: its anode's, its solid inventory's, and what its side
  // reaction has taken.
  struct Pin {
    Scalar anode_mol = Scalar(0);
    Scalar inventory_mol = Scalar(0);
    Scalar loss_mol = Scalar(0);
  };

  explicit AreaScale(const Config& c) : c_(c) {}

  bool enabled() const { return c_.enabled; }
  // The scale in use: 1 until a span has measured it (and always when off).
  Scalar scale() const { return s_.scale; }
  // The current the model is driven with: the cell's current in the nominal cell's units.
  Scalar model_current_a(Scalar current_a) const { return c_.model_sees ? current_a / s_.scale : current_a; }
  // The model's current back in the cell's amperes (for the outputs).
  Scalar cell_current_a(Scalar model_current_a) const { return c_.model_sees ? model_current_a * s_.scale : model_current_a; }
  bool model_sees() const { return c_.enabled && c_.model_sees; }

  // Step 2: the accepted sample's current over this tick and the `missed` ticks before it.
  void count(Scalar current_a, std::uint32_t missed) {
    if (!c_.enabled || !(s_.flags & 1u) || !std::isfinite(current_a)) return;
    const Scalar y = current_a * c_.dt_s * (Scalar(1) + static_cast<Scalar>(missed)) / Scalar(kFaradayC_mol) +
                     s_.counted_carry_mol;
    const Scalar sum = s_.counted_mol + y;
    s_.counted_carry_mol = y - (sum - s_.counted_mol);
    s_.counted_mol = sum;
  }

  // Step 7: a CV end. `end` is the model as the voltage-driven CV phase left it (the span's end,
  // at the span's inventory), `next` after this CV end's re-synchronisation (the next span's
  // start; `end` where none moved it). Returns true when a span measured a.
  // `capacity_ah(n)` is the nominal electrodes' open-circuit capacity at inventory n (less the
  // model's loss), called twice when a span is measured at an inventory other than the last one's.
  template <class CapacityOf>
  bool pin(const Pin& end, const Pin& next, const CapacityOf& capacity_ah) {
    if (!c_.enabled || !finite(end) || !finite(next)) return false;
    bool measured = false;
    const Scalar q = s_.counted_mol + s_.counted_carry_mol;
    const Scalar span_inventory_mol = end.inventory_mol + end.loss_mol;
    if ((s_.flags & 1u) && std::fabs(q) >= c_.min_span_mol && c_.min_span_mol > Scalar(0)) {
      const Scalar moved_mol = (end.anode_mol - s_.pinned_anode_mol) + (end.loss_mol - s_.pinned_loss_mol);
      if ((s_.flags & 2u) && span_inventory_mol != s_.span_inventory_mol) {
        carry_to(capacity_ah(s_.span_inventory_mol - end.loss_mol) / capacity_ah(span_inventory_mol - end.loss_mol));
      }
      if (take_span(-q / moved_mol, q)) {
        measured = true;
        s_.span_inventory_mol = span_inventory_mol;
        s_.flags |= 2u;
      }
    }
    s_.pinned_anode_mol = next.anode_mol;
    s_.pinned_loss_mol = next.loss_mol;
    s_.counted_mol = Scalar(0);
    s_.counted_carry_mol = Scalar(0);
    s_.flags |= 1u;
    return measured;
  }

  // A model without a capacity: spans are combined as scales.
  bool pin(const Pin& end, const Pin& next) {
    return pin(end, next, [](Scalar) { return Scalar(1); });
  }
  // A CV end no re-synchronisation moved the model at.
  bool pin(const Pin& at) { return pin(at, at); }

  // The model's inventory (plus its lithium loss) over the span that measured a: the capacity's
  // inventory, consistent with a (the span's charge is a times the model's anode move at that
  // inventory); NaN before any span.
  Scalar span_inventory_mol() const {
    return (s_.flags & 2u) ? s_.span_inventory_mol : std::numeric_limits<Scalar>::quiet_NaN();
  }

  // The model was moved other than at a CV end (a power-up re-synchronisation after a gap): the
  // last pin no longer holds at its inventory (at the upper end the move would read as area), so
  // the next CV end starts a span instead of ending one.
  void unpin() { s_.flags &= ~1u; }

  // The current sensor's offset in use changed: the spans counted with the old one are dropped
  // (the scale in use is kept as the start; the next span replaces it).
  void forget() { s_.weight = Scalar(0); }

  State save() const { return s_; }
  bool restore(const State& s) {
    const bool ok = std::isfinite(s.scale) && std::fabs(s.scale - Scalar(1)) <= c_.limit && std::isfinite(s.weight) &&
                    s.weight >= Scalar(0) && std::isfinite(s.counted_mol) && std::isfinite(s.counted_carry_mol) &&
                    std::isfinite(s.pinned_anode_mol) && std::isfinite(s.pinned_loss_mol) && std::isfinite(s.span_inventory_mol) && (s.flags & ~3u) == 0u;
    if (!ok) return false;
    s_ = s;
    return true;
  }
  const Config& config() const { return c_; }

 private:
  static bool finite(const Pin& p) {
    return std::isfinite(p.anode_mol) && std::isfinite(p.inventory_mol) && std::isfinite(p.loss_mol);
  }

  // The kept scale to another inventory; a ratio that is not a plausible one leaves it.
  void carry_to(Scalar ratio) {
    const Scalar carried = s_.scale * ratio;
    if (std::isfinite(carried) && std::fabs(carried - Scalar(1)) <= c_.limit) s_.scale = carried;
  }

  bool take_span(Scalar a, Scalar q) {
    if (!std::isfinite(a) || !(std::fabs(a - Scalar(1)) <= c_.limit)) return false;
    const Scalar w = q * q, kept = c_.memory * s_.weight;
    s_.scale = (kept * s_.scale + w * a) / (kept + w);
    s_.weight = kept + w;
    return true;
  }

  Config c_;
  State s_{Scalar(1), Scalar(0), Scalar(0), Scalar(0), Scalar(0), Scalar(0), Scalar(0), 0u};
};

}  // namespace bms::fw
