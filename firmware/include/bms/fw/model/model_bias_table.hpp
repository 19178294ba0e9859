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

}  // namespace bms::fw
