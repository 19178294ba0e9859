#pragma once
// The paper-reproduction cell (LiFePO4/graphite, A123 26650 type; Forman et al. 2012 geometry)
// with the Ramadass side reaction as the paper prints it. This header is the single source of
// truth: the host simulator builds its `paper` parameter set from it (host_sim/src/cell/
// paper_cell.cpp) and a test checks the two agree. Choices among the sources' disagreements
// are documented in docs/parameters.md.
// The functions are templated so the same code serves double, float and dual numbers.
#include <cmath>
#include <type_traits>

namespace bms::fw::paper {

namespace detail {

// float, and any number type over float (the dual numbers of the float build's CV step).
template <typename T> struct SinglePrecision : std::is_same<T, float> {};
template <template <typename> class N> struct SinglePrecision<N<float>> : std::true_type {};

// Sum of coefficient x term in single precision. The open-circuit potentials add terms of size
// 10 that cancel to a few volts or tenths of a volt; rounding each coefficient to float moves
// each term by up to 5e-7 V, and these do not average out: a systematic error of 2-5e-7 V in
// each potential (measured as the mean over 2e-3 of stoichiometry against double), a third of
// the film's signal over a charge. Each coefficient is therefore split into its float value and
// the rest, and the rests' contributions are summed apart and added once the large terms have
// cancelled (mean error then below 1e-7 V).
template <typename T>
struct SplitSum {
  T sum{};
  T low{};
  void add(double c, const T& term) {
    const float hi = static_cast<float>(c);
    const float lo = static_cast<float>(c - static_cast<double>(hi));
    sum = sum + term * hi;
    low = low + term * lo;
  }
  T value() const { return sum + low; }
};

template <typename T>
T ocp_positive_split(T x) {
  using std::exp; using std::sqrt; using std::tanh;
  const T sx = sqrt(x);
  const T one = T(1.0f);
  SplitSum<T> s;
  s.add(7.49983, one);
  s.add(-13.7758, sx);
  s.add(21.7683, x);
  s.add(-12.6985, x * sx);
  s.add(0.0174967, one / x);
  s.add(-0.41649, one / sx);
  s.add(-0.0161404, exp(x * 100.0f - 97.1069f));
  s.add(0.363031, tanh(x * 5.89493f - 4.21921f));
  return s.value();
}

template <typename T>
T ocp_negative_split(T x) {
  using std::exp; using std::sqrt; using std::tanh;
  const T sx = sqrt(x);
  const T one = T(1.0f);
  SplitSum<T> s;
  s.add(9.99877, one);
  s.add(-9.99961, sx);
  s.add(-9.98836, x);
  s.add(8.2024, x * sx);
  s.add(0.23584, one / x);
  s.add(-2.03569, one / sx);
  s.add(-1.47266, exp(x * -1.14872f + 2.13185f));
  s.add(-9.9989, tanh(x * 0.60345f - 1.58171f));
  return s.value();
}

}  // namespace detail

struct Electrode {
  double thickness_m;
  double particle_radius_m;
  double solid_fraction;
  double porosity;
  double solid_diffusivity_m2_s;
  double max_concentration_mol_m3;
  double conductivity_eff_s_m;  // 100 S/m placeholder times eps_s (scott-moura/dfn params.m)
  double i0_coefficient;        // F k in i0 = F k sqrt(c_e c_s (c_max - c_s)) [A/m2]
  double stoich_init;
};

inline constexpr Electrode kNegative{28.85e-6, 3.596e-6, 0.381, 0.619, 1.736e-14, 29480.0,
                                     100.0 * 0.381, 8.696e-7, 0.8408};
inline constexpr Electrode kPositive{65.21e-6, 0.1637e-6, 0.48, 0.52, 8.256e-14, 10350.0,
                                     100.0 * 0.48, 1.127e-7, 0.1592};
inline constexpr double kSeparatorThickness_m = 16.97e-6;
inline constexpr double kSeparatorPorosity = 0.3041;
inline constexpr double kBruggeman = 1.452;
inline constexpr double kTransference = 0.2495;
inline constexpr double kElectrolyteInit_mol_m3 = 1266.9;  // the paper's c2 (printed as mol/dm3)
inline constexpr double kElectrodeArea_m2 = 0.3108;
inline constexpr double kTemperature_k = 298.15;
inline constexpr double kLowerVoltage_v = 2.0;
inline constexpr double kUpperVoltage_v = 3.6;
inline constexpr double kCurrent_a = 2.5;            // the paper's CC magnitude
inline constexpr double kCvEndCurrent_a = 0.125;     // our choice: C/20 of 2.5 A (paper silent)
inline constexpr double kNominalCapacity_ah = 2.3;

// Ramadass side reaction, paper's printed values (M_p = 7.3e4 kg/mol: see docs/parameters.md).
inline constexpr double kSideRefPotential_v = 0.4;
inline constexpr double kSideExchange_a_m2 = 4e-9;
inline constexpr double kSideAlpha = 0.5;
inline constexpr double kFilmMolarMass_kg_mol = 7.3e4;
inline constexpr double kFilmDensity_kg_m3 = 2.1e3;
inline constexpr double kFilmConductivity_s_m = 1.0;
inline constexpr double kInitialFilm_ohm_m2 = 3.391e-3;

// Open-circuit potentials (public fits used with this geometry; origin probably Forman's
// identification). x is the stoichiometry.
// In single precision the same functions through detail::SplitSum (the coefficients as below;
// tests/firmware/test_float_numerics.cpp holds the two forms together).
template <typename T>
T ocp_positive_v(T x) {
  if constexpr (detail::SinglePrecision<T>::value) {
    return detail::ocp_positive_split(x);
  } else {
    using std::exp; using std::sqrt; using std::tanh;
    const T sx = sqrt(x);
    return T(7.49983) - T(13.7758) * sx + T(21.7683) * x - T(12.6985) * x * sx + T(0.0174967) / x -
           T(0.41649) / sx - T(0.0161404) * exp(T(100.0) * x - T(97.1069)) +
           T(0.363031) * tanh(T(5.89493) * x - T(4.21921));
  }
}

template <typename T>
T ocp_negative_v(T x) {
  if constexpr (detail::SinglePrecision<T>::value) {
    return detail::ocp_negative_split(x);
  } else {
    using std::exp; using std::sqrt; using std::tanh;
    const T sx = sqrt(x);
    return T(9.99877) - T(9.99961) * sx - T(9.98836) * x + T(8.2024) * x * sx + T(0.23584) / x -
           T(2.03569) / sx - T(1.47266) * exp(T(-1.14872) * x + T(2.13185)) -
           T(9.9989) * tanh(T(0.60345) * x - T(1.58171));
  }
}

template <typename T>
T electrolyte_diffusivity_m2_s(T c_mol_m3) {
  using std::exp;
  return T(5.34e-10) * exp(T(-0.65e-3) * c_mol_m3);
}

template <typename T>
T electrolyte_conductivity_s_m(T c_mol_m3) {
  const T c = c_mol_m3 * T(1e-3);
  return T(0.0911) + T(1.9101) * c - T(1.052) * c * c + T(0.1554) * c * c * c;
}

}  // namespace bms::fw::paper
