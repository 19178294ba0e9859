#pragma once
// The reduced model's design-time voltage bias as a function of its state of charge: a table of
// the bias per ampere of charge current [ohm] over the model's own mean anode stoichiometry,
// added to the constant design-time bias (IdentifierFilmPath::Config::model_bias_ohm). Computed
// once at design time against a DFN of the nominal cell (host_sim estimation/design_bias.hpp),
// never against the cell in use. Where the reduced model's error varies over a CC charge (thick
// electrodes, a flat OCP whose reaction runs as a front), a constant removes only its median and
// the identification puts the rest into the film and its growth; the table removes its shape.
// Knots evenly spaced over [x_first, x_last]; linear between knots, the end knot's value
// outside. Off (x_last <= x_first, the default): the bias is the constant alone, bit for bit.
// Firmware rules: fixed size, no heap.
#include <cmath>
#include <limits>
#include <type_traits>
#include <utility>

namespace bms::fw {

inline constexpr int kModelBiasKnots = 24;

// Whether a main-system model gives its mean anode stoichiometry (mean_stoich_neg()), the table's
// abscissa: the reduced model does (and EffectsModel over it); the host's full DFN does not.
template <typename Model, typename Scalar, typename = void>
inline constexpr bool kGivesStoichiometry = false;
template <typename Model, typename Scalar>
inline constexpr bool kGivesStoichiometry<Model, Scalar,
                                          std::void_t<decltype(std::declval<const Model&>().mean_stoich_neg())>> = true;

template <typename Scalar = double>
struct ModelBiasTable {
  static constexpr int kKnots = kModelBiasKnots;
  Scalar x_first = Scalar(0);  // mean anode stoichiometry of the first knot
  Scalar x_last = Scalar(0);   // of the last knot
  Scalar ohm[kKnots] = {};     // bias per ampere of charge current at each knot [ohm]
  // The same calibration's trusted span: above this mean anode stoichiometry the reduced model
  // leaves the nominal cell by more than a median can remove (a flat-OCP cell's end-of-charge
  // knee), so a residual there is not the film's and a CC charge's learning stops
  // (IdentifierFilmPath). +inf: trusted everywhere (the default, and a table that is off).
  Scalar x_trusted_last = std::numeric_limits<Scalar>::infinity();

  bool on() const { return x_last > x_first; }

  // Finite knots over a finite, increasing span (or off).
  bool valid() const {
    if (!std::isfinite(x_first) || !std::isfinite(x_last) || x_last < x_first) return false;
    if (std::isnan(x_trusted_last)) return false;
    for (Scalar v : ohm)
      if (!std::isfinite(v)) return false;
    return true;
  }

  // The bias per ampere at stoichiometry x [ohm]; 0 when off or x is not finite.
  Scalar at(Scalar x) const {
    if (!on() || !std::isfinite(x)) return Scalar(0);
    const Scalar step = (x_last - x_first) / Scalar(kKnots - 1);
    const Scalar s = (x - x_first) / step;
    if (!(s > Scalar(0))) return ohm[0];
    if (!(s < Scalar(kKnots - 1))) return ohm[kKnots - 1];
    const int k = static_cast<int>(s);
    const Scalar f = s - Scalar(k);
    return ohm[k] + f * (ohm[k + 1] - ohm[k]);
  }

  // The same table in another scalar type (the configuration is computed in double).
  template <typename Other>
  ModelBiasTable<Other> as() const {
    ModelBiasTable<Other> t;
    t.x_first = Other(x_first);
    t.x_last = Other(x_last);
    t.x_trusted_last = Other(x_trusted_last);
    for (int k = 0; k < kKnots; ++k) t.ohm[k] = Other(ohm[k]);
    return t;
  }
};

// The same calibration at three lithium inventories (issue 28): the nominal DFN run with its
// inventory at -step, 0 and +step of nominal, each level the table of the reduced model placed at
// that inventory. With another inventory than nominal the cathode sits elsewhere for the same
// anode stoichiometry, and a table of the nominal inventory reads the difference as film
// (measured: docs/results/firmware-model.md). Read as the parabola through the three levels at an
// inventory deviation within +-step (the end level's value outside), with its slope over the
// inventory: the film path evaluates it where its model is placed and adds the slope to the
// inventory's sensitivity, so that a fit that moves the inventory moves the bias with it.
// nu_step 0 (the default): the nominal level alone, bit for bit as a single table.
inline constexpr int kModelBiasLevels = 3;

template <typename Scalar = double>
struct ModelBiasTables {
  static constexpr int kLevels = kModelBiasLevels;
  static constexpr int kNominal = kLevels / 2;
  static_assert(kLevels == 3, "a parabola through lean, nominal and rich");
  ModelBiasTable<Scalar> level[kLevels] = {};  // at inventory deviation (k - kNominal) * nu_step
  Scalar nu_step = Scalar(0);                  // relative inventory between levels (0: the nominal level alone)
  // The calibration's coverage of a CC charge (IdentifierFilmPath's start condition of a charge's
  // fusion). The bias is calibrated on charges at 1C from the bottom of the window; at another
  // charge current, or on the constant alone (a charge begun above the table's start margin), the
  // reduced model may leave the nominal cell by more than the film the charge is to identify, and
  // fused, that misfit is read as film and growth. covered_charge_a_min: the lowest charge current
  // [A] the calibration found the bias fits at (0: every current). constant_alone_covered: the
  // constant alone fits the calibration's charges.
  Scalar covered_charge_a_min = Scalar(0);
  bool constant_alone_covered = true;

  const ModelBiasTable<Scalar>& nominal() const { return level[kNominal]; }
  ModelBiasTable<Scalar>& nominal() { return level[kNominal]; }
  bool on() const { return nominal().on(); }
  bool by_inventory() const { return nu_step > Scalar(0); }

  bool valid() const {
    if (!std::isfinite(nu_step) || nu_step < Scalar(0)) return false;
    if (!std::isfinite(covered_charge_a_min) || covered_charge_a_min < Scalar(0)) return false;
    for (const auto& t : level)
      if (!t.valid()) return false;
    return true;
  }

  // The bias per ampere at stoichiometry x and inventory deviation nu [ohm], and its slope over
  // the inventory deviation [ohm per unit of nu; 0 outside +-step and without levels]: one
  // lookup per level for both.
  struct Reading {
    Scalar ohm;
    Scalar slope;
  };
  Reading read(Scalar x, Scalar nu) const {
    if (!by_inventory()) return {nominal().at(x), Scalar(0)};
    const Scalar s = clamped(nu), b0 = level[0].at(x), b1 = level[1].at(x), b2 = level[2].at(x);
    const Scalar half_span = Scalar(0.5) * (b2 - b0), curve = b2 - Scalar(2) * b1 + b0;
    const bool inside = s == nu / nu_step;
    return {b1 + s * half_span + s * s * Scalar(0.5) * curve, inside ? (half_span + s * curve) / nu_step : Scalar(0)};
  }
  Scalar at(Scalar x, Scalar nu) const { return read(x, nu).ohm; }
  Scalar slope(Scalar x, Scalar nu) const { return read(x, nu).slope; }
  // The trusted span's end at inventory deviation nu: linear between two finite ends, else the
  // nearer level's (+inf: trusted everywhere).
  Scalar trusted_last(Scalar nu) const {
    if (!by_inventory()) return nominal().x_trusted_last;
    const Scalar s = clamped(nu);
    const int k = s < Scalar(0) ? 0 : 1;
    const Scalar f = s < Scalar(0) ? s + Scalar(1) : s;  // the weight of level k + 1
    const Scalar a = level[k].x_trusted_last, b = level[k + 1].x_trusted_last;
    if (std::isfinite(a) && std::isfinite(b)) return a + f * (b - a);
    return f < Scalar(0.5) ? a : b;
  }
  // Whether a CC charge at charge_a [A] (positive) is covered, given whether it met the table's
  // start condition.
  bool covers(Scalar charge_a, bool table_in_charge) const {
    if (charge_a < covered_charge_a_min) return false;
    return table_in_charge || !on() || constant_alone_covered;
  }
  bool has_trusted_span() const {
    for (const auto& t : level)
      if (std::isfinite(t.x_trusted_last)) return true;
    return false;
  }

  // --no-bias-table: every level's knots off, each level's trusted span kept.
  void drop_knots() {
    for (auto& t : level) {
      const Scalar end = t.x_trusted_last;
      t = ModelBiasTable<Scalar>{};
      t.x_trusted_last = end;
    }
  }
  // --trusted-span-end / --no-trusted-span: one end for every level.
  void set_trusted_last(Scalar x) {
    for (auto& t : level) t.x_trusted_last = x;
  }

  template <typename Other>
  ModelBiasTables<Other> as() const {
    ModelBiasTables<Other> t;
    for (int k = 0; k < kLevels; ++k) t.level[k] = level[k].template as<Other>();
    t.nu_step = Other(nu_step);
    t.covered_charge_a_min = Other(covered_charge_a_min);
    t.constant_alone_covered = constant_alone_covered;
    return t;
  }

 private:
  // nu in units of the step, within [-1, 1] (NaN: the nominal level).
  Scalar clamped(Scalar nu) const {
    const Scalar s = nu / nu_step;
    if (std::isnan(s)) return Scalar(0);
    return s < Scalar(-1) ? Scalar(-1) : s > Scalar(1) ? Scalar(1) : s;
  }
};

}  // namespace bms::fw
