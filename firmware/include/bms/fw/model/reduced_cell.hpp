#pragma once
// Reduced-order DFN for the firmware: the main-system model of RCSI.
//
// What is kept from the truth DFN (host_sim/src/dfn/dfn_model.cpp), in the same finite-volume
// form so the two can be compared term by term:
//   - electrolyte concentration on a coarse x mesh (Nn + Ns + Np cells, concentration-
//     dependent D_e and kappa, diffusion potential), electrolyte potential from the ionic
//     current;
//   - one particle per electrode on NrN / NrP shells refined towards the surface, with the
//     truth's surface extrapolation;
//   - Butler-Volmer kinetics per electrolyte cell (local c_e) with the film drop j R_film,
//     the Ramadass side reaction inside it, and the lithium it consumes (eq. 10): the
//     intercalation flux is j - j_s, so lithium leaves the cyclable inventory.
// What is reduced: the reaction current density is uniform within each electrode (single-
// particle assumption: the solid potential is taken as the mean over the electrode's cells
// of phi_e + U + eta + j R_film). The film resistance is an input (no eqs 11-12).
//
// Time stepping: backward Euler over one tick. Particles and electrolyte are linear in the
// next state once D_e is taken at the start of the tick, so each is one tridiagonal solve;
// the kinetics are closed-form (asinh) with a fixed number of side-reaction fixed-point
// passes. Current-driven (CC, rest) costs one evaluation. Voltage-driven (CV) solves
// V(I) = V_measured by Newton on the current with an exact derivative (dual numbers), capped
// at kMaxNewtonIterations: every tick has a fixed worst case.
//
// Precision (Scalar = float on a Cortex-M4F; docs/results/target.md, "Float"): the film's signal
// is about 1e-5 of the terminal voltage, so the state is advanced in increments, never
// recomputed from absolute values: each implicit step solves for the change of every
// concentration (the diffusion right-hand side uses differences of neighbours, which float
// subtracts exactly), and the change is added with a carried compensation term (Kahan), so
// the lithium inventory is conserved to round-off instead of drifting by the rounding of the
// step's constants every tick (measured in float: -2.3e-4 of the inventory per cycle before).
//
// Firmware rules: compile-time sizes, no heap, no exceptions, no RTTI, no globals.
#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>
#include <utility>

#include "bms/fw/model/dual.hpp"
#include "bms/fw/model/open_circuit_capacity.hpp"
#include "bms/fw/model/paper_cell.hpp"
#include "bms/fw/model/physical_constants.hpp"

namespace bms::fw {

// Compile-time mesh of the reduced model.
template <int Nn = 3, int Ns = 1, int Np = 3, int NrN = 16, int NrP = 2>
struct ReducedMesh {
  static_assert(Nn >= 1 && Ns >= 1 && Np >= 1 && NrN >= 1 && NrP >= 1, "mesh sizes must be >= 1");
  static constexpr int kNeg = Nn, kSep = Ns, kPos = Np, kShellsNeg = NrN, kShellsPos = NrP;
  static constexpr int kCells = Nn + Ns + Np;
};

// How the cell's properties move with temperature: the nominal Arrhenius activation energies
// [J/mol] of its solid diffusivities, reaction rates, electrolyte diffusivity and conductivity and
// side reaction, about a reference temperature, and the entropic coefficients dU/dT [V/K] of its
// open-circuit potentials where the cell gives them. A cell's traits carry them as a nested
// `Temperature` type with these members; traits without it are taken as isothermal data at their
// kTemperatureK (every activation energy 0, no entropic term): the thermal voltage RT/F still
// follows the measured temperature, as it does in the truth.
// The members of isothermal data but the reference temperature (shared with host traits whose
// reference is known only at run time).
struct IsothermalProperties {
  static constexpr double kNegDiffusivityActivationJMol = 0.0;
  static constexpr double kPosDiffusivityActivationJMol = 0.0;
  static constexpr double kNegRateActivationJMol = 0.0;
  static constexpr double kPosRateActivationJMol = 0.0;
  static constexpr double kElectrolyteDiffusivityActivationJMol = 0.0;
  static constexpr double kElectrolyteConductivityActivationJMol = 0.0;
  static constexpr double kSideActivationJMol = 0.0;
  static constexpr bool kHasEntropic = false;
  template <typename T> static T entropic_neg_v_k(T /*stoich*/) { return T(0); }
  template <typename T> static T entropic_pos_v_k(T /*stoich*/) { return T(0); }
};

template <typename Cell>
struct NoTemperatureData : IsothermalProperties {
  static constexpr double kReferenceK = Cell::kTemperatureK;
};

template <typename Cell, typename = void>
struct TemperatureDataOf {
  using type = NoTemperatureData<Cell>;
};
template <typename Cell>
struct TemperatureDataOf<Cell, std::void_t<typename Cell::Temperature>> {
  using type = typename Cell::Temperature;
};

struct PaperCellTemperatureBase {
  static constexpr double kTemperatureK = paper::kTemperature_k;
};

// The paper cell as the reduced model sees it. Numbers come from bms/fw/model/paper_cell.hpp (one
// source of truth with the host simulator).
struct PaperCellTraits {
  static constexpr double kAreaM2 = paper::kElectrodeArea_m2;
  static constexpr double kTemperatureK = paper::kTemperature_k;
  static constexpr double kTransference = paper::kTransference;
  static constexpr double kElectrolyteInitMolM3 = paper::kElectrolyteInit_mol_m3;
  static constexpr double kSeparatorThicknessM = paper::kSeparatorThickness_m;
  static constexpr double kSeparatorPorosity = paper::kSeparatorPorosity;
  static constexpr double kBruggeman = paper::kBruggeman;
  static constexpr paper::Electrode kNeg = paper::kNegative;
  static constexpr paper::Electrode kPos = paper::kPositive;
  static constexpr double kSideRefPotentialV = paper::kSideRefPotential_v;
  static constexpr double kSideExchangeAM2 = paper::kSideExchange_a_m2;
  static constexpr double kSideAlpha = paper::kSideAlpha;
  static constexpr double kInitialFilmOhmM2 = paper::kInitialFilm_ohm_m2;
  static constexpr double kFilmMolarMassKgMol = paper::kFilmMolarMass_kg_mol;
  static constexpr double kFilmDensityKgM3 = paper::kFilmDensity_kg_m3;
  static constexpr double kFilmConductivitySM = paper::kFilmConductivity_s_m;
  static constexpr double kUpperVoltageV = paper::kUpperVoltage_v;
  static constexpr double kLowerVoltageV = paper::kLowerVoltage_v;
  static constexpr double kNominalCapacityAh = paper::kNominalCapacity_ah;
  // The paper cell's temperature data: no activation energies and no entropic coefficients
  // (host_sim/src/cell/paper_cell.cpp: Forman et al. give none; the truth's properties do not
  // move with temperature except through RT/F, in its kinetics, diffusion potential and side
  // reaction). A cell with Arrhenius data sets them here.
  struct Temperature : NoTemperatureData<PaperCellTemperatureBase> {};
  template <typename T> static T ocp_neg_v(T x) { return paper::ocp_negative_v(x); }
  template <typename T> static T ocp_pos_v(T x) { return paper::ocp_positive_v(x); }
  template <typename T> static T electrolyte_diffusivity_m2_s(T c) {
    return paper::electrolyte_diffusivity_m2_s(c);
  }
  template <typename T> static T electrolyte_conductivity_s_m(T c) {
    return paper::electrolyte_conductivity_s_m(c);
  }
};

// Whether a main-system model takes the measured temperature (set_temperature_k(Scalar) -> bool):
// the reduced model does; a model without it (the host's full DFN) stays at its own temperature.
template <typename Model, typename Scalar, typename = void>
inline constexpr bool kTakesTemperature = false;
template <typename Model, typename Scalar>
inline constexpr bool kTakesTemperature<
    Model, Scalar, std::void_t<decltype(std::declval<Model&>().set_temperature_k(std::declval<Scalar>()))>> = true;

// Whether a main-system model gives its voltage at a shifted temperature (temperature_probe_voltage).
template <typename Model, typename Scalar, typename = void>
inline constexpr bool kProbesTemperature = false;
template <typename Model, typename Scalar>
inline constexpr bool kProbesTemperature<
    Model, Scalar,
    std::void_t<decltype(std::declval<const Model&>().temperature_probe_voltage(
        std::declval<Scalar>(), std::declval<Scalar>(), std::declval<Scalar>(), std::declval<Scalar>()))>> = true;

// A cell's stated parameter spread: relative 1-sigma of the anode's and the cathode's exchange
// current, of each transport property (electrolyte conductivity and diffusivity, each electrode's
// solid diffusivity, drawn independently) and of the electrode area (both electrodes' capacity
// and current density). A lot tolerance the BMS is given, not learned; 0: a characterised cell.
template <typename Scalar>
struct StatedSpread {
  Scalar anode_i0_rel = Scalar(0);
  Scalar cathode_i0_rel = Scalar(0);
  Scalar transport_rel = Scalar(0);
  Scalar area_rel = Scalar(0);
  bool any() const {
    return anode_i0_rel > Scalar(0) || cathode_i0_rel > Scalar(0) || transport_rel > Scalar(0) || area_rel > Scalar(0);
  }
};

// Whether a main-system model gives the voltage's 1-sigma for a stated spread (spread_voltage_sd_v).
template <typename Model, typename Scalar, typename = void>
inline constexpr bool kGivesSpread = false;
template <typename Model, typename Scalar>
inline constexpr bool kGivesSpread<
    Model, Scalar,
    std::void_t<decltype(std::declval<const Model&>().spread_voltage_sd_v(
        std::declval<Scalar>(), std::declval<Scalar>(), std::declval<const StatedSpread<Scalar>&>()))>> = true;

// Whether a main-system model gives the lithium its anode holds (AreaScale's pins).
template <typename Model, typename Scalar, typename = void>
inline constexpr bool kGivesAnodeLithium = false;
template <typename Model, typename Scalar>
inline constexpr bool kGivesAnodeLithium<Model, Scalar,
                                         std::void_t<decltype(std::declval<const Model&>().anode_lithium_mol())>> = true;

// Whether a main-system model gives the open-circuit capacity of an inventory (the reduced
// model does; the host's full DFN does not, and the tick then reports NaN).
template <typename Model, typename Scalar, typename = void>
inline constexpr bool kGivesCapacity = false;
template <typename Model, typename Scalar>
inline constexpr bool kGivesCapacity<Model, Scalar,
                                     std::void_t<decltype(Model::open_circuit_capacity_ah(std::declval<Scalar>()))>> =
    true;

// Result of one model tick.
template <typename Scalar>
struct ModelTickResult {
  Scalar voltage_v;                 // model terminal voltage y_hat
  Scalar current_a;                 // applied (CC) or solved (CV) current, positive = discharge
  Scalar j_side_a_m3;               // y0_hat: mean volumetric side-reaction current (negative)
  Scalar markov_v_per_ohm_m2;       // dV/dR_film at this tick (= -j_n)
  std::uint8_t newton_iterations;   // CV only
  bool converged;                   // CV Newton met its tolerance (CC: always true)
  bool valid;                       // false: state left unchanged (non-finite trial)
};

template <typename Scalar = double, typename Cell = PaperCellTraits, typename Mesh = ReducedMesh<>>
class ReducedCell {
  static_assert(std::is_floating_point<Scalar>::value, "Scalar must be a floating-point type");

 public:
  static constexpr int kNn = Mesh::kNeg, kNs = Mesh::kSep, kNp = Mesh::kPos;
  static constexpr int kNx = Mesh::kCells;
  static constexpr int kNrN = Mesh::kShellsNeg, kNrP = Mesh::kShellsPos;
  static constexpr int kNumStates = kNrN + kNrP + kNx + 2;  // + lithium lost, charge
  static constexpr int kMaxNewtonIterations = 8;
  static constexpr int kSidePasses = 2;  // j_s / j is about 1e-5: two passes reach round-off
  static constexpr double kSurfaceRefinement = 0.6;  // as the truth's shells

  // Plain-old-data state (saved to NVM with the estimator's state).
  struct State {
    Scalar cs_neg_mol_m3[kNrN];
    Scalar cs_pos_mol_m3[kNrP];
    Scalar ce_mol_m3[kNx];
    Scalar li_loss_mol;
    Scalar charge_c;        // integral of current, discharge positive
    Scalar current_a;       // last applied current (Newton start in CV)
    Scalar j_side_a_m2;     // last mean side-reaction current density (fixed-point start)
    // Stoichiometry shifts of the anode and cathode per mol of cyclable lithium that keep the
    // voltage of the last re-synchronisation (inventory_probe_voltage); 0 before the first.
    Scalar inventory_dir_neg_per_mol;
    Scalar inventory_dir_pos_per_mol;
    // Compensation terms (Kahan) of the accumulated states: the low-order part of each
    // value that its Scalar could not hold; value = stored + carry.
    Scalar cs_neg_carry_mol_m3[kNrN];
    Scalar cs_pos_carry_mol_m3[kNrP];
    Scalar ce_carry_mol_m3[kNx];
    Scalar li_loss_carry_mol;
  };
  static_assert(std::is_trivially_copyable<State>::value, "State must be trivially copyable");

  using TemperatureData = typename TemperatureDataOf<Cell>::type;

  ReducedCell() {
    build_geometry();
    apply_temperature(Scalar(TemperatureData::kReferenceK));
  }

  // Uniform state at rest with the given stoichiometries and electrolyte concentration.
  void init(Scalar stoich_neg, Scalar stoich_pos, Scalar ce_mol_m3) {
    for (int i = 0; i < kNrN; ++i) s_.cs_neg_mol_m3[i] = stoich_neg * Scalar(Cell::kNeg.max_concentration_mol_m3);
    for (int i = 0; i < kNrP; ++i) s_.cs_pos_mol_m3[i] = stoich_pos * Scalar(Cell::kPos.max_concentration_mol_m3);
    for (int k = 0; k < kNx; ++k) s_.ce_mol_m3[k] = ce_mol_m3;
    s_.li_loss_mol = Scalar(0);
    s_.charge_c = Scalar(0);
    s_.current_a = Scalar(0);
    s_.j_side_a_m2 = Scalar(0);
    s_.inventory_dir_neg_per_mol = Scalar(0);
    s_.inventory_dir_pos_per_mol = Scalar(0);
    clear_carries();
  }
  void init_default() {
    init(Scalar(Cell::kNeg.stoich_init), Scalar(Cell::kPos.stoich_init), Scalar(Cell::kElectrolyteInitMolM3));
  }

  // The cell temperature the model's properties are taken at [K]: the measured one, which the
  // tick sets before each step. Non-finite or outside [kMinTemperatureK, kMaxTemperatureK]:
  // refused (false), the last accepted temperature stays. The thermal voltage RT/F and every
  // Arrhenius factor exp(E/R (1/T_ref - 1/T)) are formed once here, not per evaluation; at the
  // reference temperature each factor is exactly 1, so the arithmetic of a tick is the
  // isothermal model's bit for bit. Not part of State: an input, set at every tick.
  bool set_temperature_k(Scalar t_k) {
    if (!within(t_k, Scalar(kMinTemperatureK), Scalar(kMaxTemperatureK))) return false;
    if (t_k != temperature_k_) apply_temperature(t_k);
    return true;
  }
  Scalar temperature_k() const { return temperature_k_; }
  // The range the cell's parameter sets are given for (the truth's --set temperature_k range).
  static constexpr double kMinTemperatureK = 233.15;
  static constexpr double kMaxTemperatureK = 353.15;

  const State& state() const { return s_; }
  static bool within(Scalar v, Scalar lo, Scalar hi) { return std::isfinite(v) && v >= lo && v <= hi; }
  // Accepts only a plausible state (a saved image may be corrupt yet CRC-valid, e.g. written by
  // a faulty build; finite alone let a lithium loss of 1e308 through). The bounds are not the
  // physical limits: under implausible inputs (tests/firmware/test_tick_property.cpp) the
  // model's own steps take a shell a little below 0 or above its maximum, and every state the
  // model reaches must restore. So: concentrations within one maximum beyond [0, max],
  // electrolyte within kMaxElectrolyteFactor times its initial value either way, lithium lost
  // within all the lithium both electrodes can hold either way, current and side current
  // within generous bounds; far outside any of them the arithmetic of a tick breaks down.
  bool restore(const State& s) {
    const Scalar li_max = inventory_of(Scalar(1), Scalar(1));
    bool ok = within(s.li_loss_mol, -li_max, li_max) && within(s.li_loss_carry_mol, -li_max, li_max) &&
              within(s.charge_c, -Scalar(kMaxChargeThroughput_c), Scalar(kMaxChargeThroughput_c)) &&
              within(s.current_a, -Scalar(kMaxCurrent_a), Scalar(kMaxCurrent_a)) &&
              within(s.j_side_a_m2, -Scalar(kMaxSideCurrent_a_m2), Scalar(kMaxSideCurrent_a_m2)) &&
              std::isfinite(s.inventory_dir_neg_per_mol) && std::isfinite(s.inventory_dir_pos_per_mol);
    const Scalar neg_max = Scalar(Cell::kNeg.max_concentration_mol_m3);
    const Scalar pos_max = Scalar(Cell::kPos.max_concentration_mol_m3);
    for (int i = 0; ok && i < kNrN; ++i) ok = within(s.cs_neg_mol_m3[i], -neg_max, Scalar(2) * neg_max);
    for (int i = 0; ok && i < kNrP; ++i) ok = within(s.cs_pos_mol_m3[i], -pos_max, Scalar(2) * pos_max);
    const Scalar ce_max = Scalar(kMaxElectrolyteFactor * Cell::kElectrolyteInitMolM3);
    for (int k = 0; ok && k < kNx; ++k) ok = within(s.ce_mol_m3[k], -ce_max, ce_max);
    // The compensation carries of the float build are rounding remainders, far below the states.
    for (int i = 0; ok && i < kNrN; ++i) ok = within(s.cs_neg_carry_mol_m3[i], -neg_max, neg_max);
    for (int i = 0; ok && i < kNrP; ++i) ok = within(s.cs_pos_carry_mol_m3[i], -pos_max, pos_max);
    for (int k = 0; ok && k < kNx; ++k) ok = within(s.ce_carry_mol_m3[k], -ce_max, ce_max);
    if (!ok) return false;
    s_ = s;
    return true;
  }
  // Bounds of restore(): far outside any state this model reaches, inside what the arithmetic
  // of one tick keeps finite.
  static constexpr double kMaxChargeThroughput_c = 1e12;  // about 3e5 full cycles of a 1 Ah cell
  static constexpr double kMaxCurrent_a = 1e4;
  static constexpr double kMaxSideCurrent_a_m2 = 1e3;
  static constexpr double kMaxElectrolyteFactor = 10.0;

  // One tick driven by current [A], positive = discharge.
  ModelTickResult<Scalar> step_current(Scalar current_a, Scalar r_film_ohm_m2, Scalar dt_s) {
    Trial<Scalar> t{};
    evaluate(current_a, r_film_ohm_m2, dt_s, t);
    ModelTickResult<Scalar> r{t.voltage_v, current_a, t.j_side_a_m3, -t.j_neg_a_m2, 0, true, false};
    r.valid = commit(t, current_a, dt_s);
    return r;
  }

  // One tick driven by terminal voltage [V] (constant-voltage phases): finds the current.
  ModelTickResult<Scalar> step_voltage(Scalar voltage_v, Scalar r_film_ohm_m2, Scalar dt_s) {
    using D = Dual<Scalar>;
    Scalar current = s_.current_a;
    bool converged = false;
    std::uint8_t it = 0;
    Trial<D> td{};
    while (it < kMaxNewtonIterations) {
      ++it;
      evaluate(D(current, Scalar(1)), r_film_ohm_m2, dt_s, td);
      const Scalar residual = td.voltage_v.v - voltage_v;
      const Scalar slope = td.voltage_v.d;  // dV/dI < 0 for a physical cell
      if (!std::isfinite(residual) || !std::isfinite(slope) || slope >= Scalar(0)) break;
      Scalar delta = -residual / slope;
      // A Newton step larger than the cell could carry is a wild iterate: limit it.
      const Scalar max_step = Scalar(kMaxNewtonStepA);
      if (delta > max_step) delta = max_step;
      if (delta < -max_step) delta = -max_step;
      current += delta;
      if (std::fabs(residual) < Scalar(kVoltageToleranceV)) {
        converged = true;
        break;
      }
    }
    Trial<Scalar> t{};
    evaluate(current, r_film_ohm_m2, dt_s, t);
    ModelTickResult<Scalar> r{t.voltage_v, current, t.j_side_a_m3, -t.j_neg_a_m2, it, converged, false};
    r.valid = commit(t, current, dt_s);
    return r;
  }

  // Terminal voltage of the current state at a given current, without advancing (dt -> 0 is
  // not meaningful for backward Euler, so this evaluates a tick without committing it).
  Scalar peek_voltage(Scalar current_a, Scalar r_film_ohm_m2, Scalar dt_s) const {
    Trial<Scalar> t{};
    evaluate(current_a, r_film_ohm_m2, dt_s, t);
    return t.voltage_v;
  }

  // Terminal voltage of this tick had the cell held `d_inventory_mol` more cyclable lithium
  // since the last re-synchronisation (which fixed the voltage there, so the extra lithium is
  // split between the electrodes as the voltage allowed). Solid diffusion is linear, so in a
  // current-driven phase the difference stays a uniform shift of each particle: one extra
  // evaluation gives the model's exact response. Without a re-synchronisation: quiet NaN.
  Scalar inventory_probe_voltage(Scalar current_a, Scalar r_film_ohm_m2, Scalar dt_s, Scalar d_inventory_mol) const {
    if (s_.inventory_dir_neg_per_mol == Scalar(0) && s_.inventory_dir_pos_per_mol == Scalar(0))
      return std::numeric_limits<Scalar>::quiet_NaN();
    ReducedCell shifted = *this;
    shifted.shift(d_inventory_mol * s_.inventory_dir_neg_per_mol, d_inventory_mol * s_.inventory_dir_pos_per_mol);
    return shifted.peek_voltage(current_a, r_film_ohm_m2, dt_s);
  }

  // Terminal voltage of this tick had the cell been d_temperature_k warmer (the model's
  // temperature sensitivity: what a temperature sensor's error does to the voltage). NaN when
  // the shifted temperature is outside the model's range.
  Scalar temperature_probe_voltage(Scalar current_a, Scalar r_film_ohm_m2, Scalar dt_s, Scalar d_temperature_k) const {
    ReducedCell shifted = *this;
    if (!shifted.set_temperature_k(temperature_k_ + d_temperature_k)) return std::numeric_limits<Scalar>::quiet_NaN();
    return shifted.peek_voltage(current_a, r_film_ohm_m2, dt_s);
  }

  // The terminal voltage's 1-sigma [V] at the tick just committed (step_current / step_voltage
  // with this current) for a stated relative spread, each parameter's share in closed form from
  // the committed state and in quadrature: a kinetic overpotential 2/f asinh(j / 2 i0) at
  // i0 (1 - s) less at i0 (the larger excursion of +-s: -ln(1 - s) > ln(1 + s)); a transport
  // property's drop (electrolyte ohmic, electrolyte concentration, each electrode's surface-minus-
  // mean OCP) at quasi-steady state inversely proportional to it, so x s / (1 - s); the area's
  // the cell's whole polarisation V - OCV(mean stoichiometries) x s / (1 - s) (current density
  // per area; the capacity's shift of the stoichiometries is left to the identified inventory).
  Scalar spread_voltage_sd_v(Scalar current_a, Scalar voltage_v, const StatedSpread<Scalar>& s) const {
    const Scalar i_app = current_a / Scalar(Cell::kAreaM2);
    const Scalar j_n = i_app / Scalar(a_neg() * Cell::kNeg.thickness_m);
    const Scalar j_p = -i_app / Scalar(a_pos() * Cell::kPos.thickness_m);
    const Scalar js = s_.j_side_a_m2;
    Scalar ce[kNx];
    for (int k = 0; k < kNx; ++k) ce[k] = clamp_low(s_.ce_mol_m3[k] + s_.ce_carry_mol_m3[k]);
    const double cmax_n = Cell::kNeg.max_concentration_mol_m3, cmax_p = Cell::kPos.max_concentration_mol_m3;
    const Scalar cs_n = clamp_conc(s_.cs_neg_mol_m3[kNrN - 1] + s_.cs_neg_carry_mol_m3[kNrN - 1] -
                                       half_n_ * (j_n - js) / Scalar(kFaradayC_mol) / ds_neg_, cmax_n);
    const Scalar cs_p = clamp_conc(s_.cs_pos_mol_m3[kNrP - 1] + s_.cs_pos_carry_mol_m3[kNrP - 1] -
                                       half_p_ * j_p / Scalar(kFaradayC_mol) / ds_pos_, cmax_p);
    const Scalar kin_n = kinetic_spread_v(ce, 0, kNn, i0_coef_neg_, cs_n, cmax_n, j_n - js, s.anode_i0_rel);
    const Scalar kin_p = kinetic_spread_v(ce, kNn + kNs, kNx, i0_coef_pos_, cs_p, cmax_p, j_p, s.cathode_i0_rel);
    const Scalar inverse = spread_inverse(s.transport_rel);
    Scalar ohmic_v = Scalar(0), conc_v = Scalar(0);
    electrolyte_drops(ce, j_n, j_p, ohmic_v, conc_v);
    const Scalar mean_n = mean_stoich_neg(), mean_p = mean_stoich_pos();
    const Scalar ocv_mean = Cell::ocp_pos_v(mean_p) - Cell::ocp_neg_v(mean_n);
    const Scalar solid_n = Cell::ocp_neg_v(cs_n / Scalar(cmax_n)) - Cell::ocp_neg_v(mean_n);
    const Scalar solid_p = Cell::ocp_pos_v(cs_p / Scalar(cmax_p)) - Cell::ocp_pos_v(mean_p);
    const Scalar terms[] = {kin_n, kin_p, ohmic_v * inverse, conc_v * inverse, solid_n * inverse, solid_p * inverse,
                            (voltage_v - ocv_mean) * spread_inverse(s.area_rel)};
    Scalar sum = Scalar(0);
    for (const Scalar t : terms) sum += t * t;
    return std::sqrt(sum);
  }

  // Ramadass film growth per unit of the model's volumetric side current:
  // dR_film/dt = -nominal_film_growth_ohm_m2_per_a_m3_s() * j_side_a_m3 with the nominal paper
  // cell's constants: what a BMS knows of the law, not what the cell in use does.
  static constexpr double nominal_film_growth_ohm_m2_per_a_m3_s() {
    return Cell::kFilmMolarMassKgMol /
           (Cell::kFilmDensityKgM3 * kFaradayC_mol * Cell::kFilmConductivitySM * a_neg());
  }
  Scalar li_loss_ah() const { return li_loss_mol() * Scalar(kFaradayC_mol / 3600.0); }
  Scalar li_loss_mol() const { return s_.li_loss_mol + s_.li_loss_carry_mol; }
  Scalar mean_stoich_neg() const {
    return mean_shell(s_.cs_neg_mol_m3, s_.cs_neg_carry_mol_m3, vol_n_, kNrN) / Scalar(Cell::kNeg.max_concentration_mol_m3);
  }
  Scalar mean_stoich_pos() const {
    return mean_shell(s_.cs_pos_mol_m3, s_.cs_pos_carry_mol_m3, vol_p_, kNrP) / Scalar(Cell::kPos.max_concentration_mol_m3);
  }

  // Lithium held in the anode's particles [mol] (AreaScale's pins).
  Scalar anode_lithium_mol() const { return mean_stoich_neg() * Scalar(solid_capacity_neg_mol()); }
  // Lithium held in both particles [mol]: the cyclable inventory.
  Scalar solid_inventory_mol() const {
    return mean_stoich_neg() * Scalar(solid_capacity_neg_mol()) + mean_stoich_pos() * Scalar(solid_capacity_pos_mol());
  }
  // Open-circuit capacity [Ah] of a cell with this model's electrodes and OCPs holding
  // `inventory_mol` of cyclable lithium (bms/fw/model/open_circuit_capacity.hpp; reference temperature).
  static Scalar open_circuit_capacity_ah(Scalar inventory_mol) {
    return fw::open_circuit_capacity_ah(
        inventory_mol, Scalar(solid_capacity_neg_mol()), Scalar(solid_capacity_pos_mol()), Scalar(Cell::kLowerVoltageV),
        Scalar(Cell::kUpperVoltageV), [](Scalar x) { return Cell::ocp_neg_v(x); },
        [](Scalar y) { return Cell::ocp_pos_v(y); });
  }
  static Scalar inventory_of(Scalar stoich_neg, Scalar stoich_pos) {
    return stoich_neg * Scalar(solid_capacity_neg_mol()) + stoich_pos * Scalar(solid_capacity_pos_mol());
  }

  // State re-synchronisation (an observer step beside RCSI, for the end of a CV phase, where
  // the cell is close to equilibrium). Shifts every shell of each particle by one amount, so
  // the model keeps its own concentration gradients, such that (1) the solid inventory equals
  // `inventory_mol` and (2) the terminal voltage at the measured current equals the measured
  // voltage; the electrolyte is scaled back to its initial mean (salt is conserved). The two
  // shifts are tied by (1), which leaves one unknown; V rises monotonically with lithium moved
  // into the anode, so a bracketed regula falsi (Illinois) with a fixed iteration cap solves
  // (2). Returns false and leaves the state unchanged when no bracket exists, and at once when
  // the voltage falls as lithium moves into the anode on the way from the present state (see
  // bracket_near: the premise fails there, so a root found further on would not be the state).
  bool resync(Scalar voltage_v, Scalar current_a, Scalar r_film_ohm_m2, Scalar dt_s, Scalar inventory_mol) {
    resync_evaluations_ = 0;
    if (!std::isfinite(voltage_v) || !std::isfinite(current_a) || !std::isfinite(inventory_mol)) return false;
    // Only a voltage inside the cell's window is a state to synchronise to.
    if (voltage_v < Scalar(Cell::kLowerVoltageV - 0.5) || voltage_v > Scalar(Cell::kUpperVoltageV + 0.5)) return false;
    const State base = s_;
    const Scalar cap_n = Scalar(solid_capacity_neg_mol()), cap_p = Scalar(solid_capacity_pos_mol());
    const Scalar missing_mol = inventory_mol - solid_inventory_mol();
    // Admissible anode shift (stoichiometry units): every shell of both particles stays inside (0, 1).
    Scalar lo = Scalar(-1), hi = Scalar(1);
    auto limit = [&](const Scalar* c, int n, double cmax, Scalar scale, Scalar offset) {
      // shell stoich after the shift: c/cmax + offset + scale * dn, within [kMargin, 1 - kMargin]
      for (int i = 0; i < n; ++i) {
        const Scalar x = c[i] / Scalar(cmax) + offset;
        const Scalar a = (Scalar(kResyncMargin) - x) / scale, b = (Scalar(1 - kResyncMargin) - x) / scale;
        const Scalar mn = a < b ? a : b, mx = a < b ? b : a;
        if (mn > lo) lo = mn;
        if (mx < hi) hi = mx;
      }
    };
    limit(base.cs_neg_mol_m3, kNrN, Cell::kNeg.max_concentration_mol_m3, Scalar(1), Scalar(0));
    limit(base.cs_pos_mol_m3, kNrP, Cell::kPos.max_concentration_mol_m3, -cap_n / cap_p, missing_mol / cap_p);
    if (!(lo < hi)) return false;
    Scalar ce_mean = Scalar(0), ce_vol = Scalar(0);
    for (int k = 0; k < kNx; ++k) {
      ce_mean += s_.ce_mol_m3[k] * eps_[k] * dx_[k];
      ce_vol += eps_[k] * dx_[k];
    }
    ce_mean /= ce_vol;
    if (!(ce_mean > Scalar(0))) return false;
    const Scalar ce_scale = Scalar(Cell::kElectrolyteInitMolM3) / ce_mean;
    auto apply = [&](Scalar dn) {
      s_ = base;
      const Scalar dp = (missing_mol - cap_n * dn) / cap_p;
      for (int i = 0; i < kNrN; ++i) s_.cs_neg_mol_m3[i] += dn * Scalar(Cell::kNeg.max_concentration_mol_m3);
      for (int i = 0; i < kNrP; ++i) s_.cs_pos_mol_m3[i] += dp * Scalar(Cell::kPos.max_concentration_mol_m3);
      for (int k = 0; k < kNx; ++k) {
        s_.ce_mol_m3[k] *= ce_scale;
        s_.ce_carry_mol_m3[k] *= ce_scale;
      }
    };
    auto mismatch = [&](Scalar dn) {
      apply(dn);
      return peek_voltage(current_a, r_film_ohm_m2, dt_s) - voltage_v;
    };
    Scalar a = lo, b = hi, fa = Scalar(0), fb = Scalar(0);
    // Every evaluation counts against kResyncIterations: the tick's cost has a fixed bound.
    int used = 0;
    const Bracket near = bracket_near(mismatch, lo, hi, a, b, fa, fb, used);
    resync_evaluations_ = used;
    if (near == Bracket::not_monotone) {
      s_ = base;
      return false;
    }
    if (near == Bracket::none_near) {
      a = lo; b = hi; fa = mismatch(a); fb = mismatch(b);
      used += 2;
      resync_evaluations_ = used;
    }
    if (!std::isfinite(fa) || !std::isfinite(fb) || fa > Scalar(0) || fb < Scalar(0)) {
      s_ = base;
      return false;
    }
    const Scalar fx = regula_falsi(mismatch, a, b, fa, fb, used);
    resync_evaluations_ = used;
    // s_ already holds the state at the last point (mismatch applied it).
    if (!(std::fabs(fx) < Scalar(kResyncAcceptV))) {
      s_ = base;
      return false;
    }
    // The voltage of this state is the last mismatch's (the same evaluation): no third one.
    set_inventory_direction(current_a, r_film_ohm_m2, dt_s, voltage_v + fx);
    return true;
  }

  // The floor of a model voltage in this Scalar: 8 units in the last place of 4 V. In float the
  // terminal voltage scatters from rounding by about 1e-6 V rms (most of it in the open-circuit
  // potentials' cancelling terms of size 10; measured against double at the same state), so a
  // tighter tolerance is met only by chance and runs the iteration to its cap.
  static constexpr double kVoltageFloorV = 8.0 * 4.0 * static_cast<double>(std::numeric_limits<Scalar>::epsilon());
  static constexpr double kVoltageToleranceV = kVoltageFloorV > 1e-9 ? kVoltageFloorV : 1e-9;
  static constexpr double kInventoryProbeStoich = 1e-3;
  static constexpr double kMaxNewtonStepA = 20.0;
  static constexpr double kResyncMargin = 1e-3;
  static constexpr double kResyncToleranceV = kVoltageFloorV > 1e-7 ? kVoltageFloorV : 1e-7;
  // Evaluations of the re-synchronisation (bracket and regula falsi together): in float on a
  // Cortex-M4F one costs about 9 600 instructions, so 18, plus the two of the inventory
  // direction, keep a re-synchronising CV tick under 300 000 with its Newton step at the cap
  // (96 500). A root near the present state takes 3-6 (bracket_near).
  static constexpr int kResyncIterations = sizeof(Scalar) >= sizeof(double) ? 40 : 18;
  static constexpr double kResyncAcceptV = 1e-4;
  static constexpr double kResyncFirstStep = 1e-3;  // anode stoichiometry: about 1-10 mV
  static constexpr int kResyncBracketSteps = 6;
  // A bracket end's mismatch beyond which the regula falsi bisects (far_end): above any the
  // method meets near a cell's state (the target lies within 0.5 V of the cell's window).
  static constexpr double kResyncFarEndV = 1.0;
  // Most model evaluations a re-synchronisation that gives up on a voltage that does not rise
  // with anode lithium can spend: the present state and the bracket's steps (bracket_near).
  static constexpr int kResyncNotMonotoneEvaluations = 1 + kResyncBracketSteps;
  // Model evaluations (peek_voltage) the last resync() spent, for its cost bound's test.
  int resync_evaluations() const { return resync_evaluations_; }

 private:
  void shift(Scalar d_stoich_neg, Scalar d_stoich_pos) {
    for (int i = 0; i < kNrN; ++i) s_.cs_neg_mol_m3[i] += d_stoich_neg * Scalar(Cell::kNeg.max_concentration_mol_m3);
    for (int i = 0; i < kNrP; ++i) s_.cs_pos_mol_m3[i] += d_stoich_pos * Scalar(Cell::kPos.max_concentration_mol_m3);
  }

  // Illinois regula falsi on the bracket [a, b] (f(a) <= 0 <= f(b)) until |f| is within
  // kResyncToleranceV or the evaluations reach kResyncIterations; returns the last f (non-
  // finite when an evaluation was). While an end is beyond kResyncFarEndV it bisects (far_end),
  // and from then on scales a retained end by Anderson-Bjorck's factor (retained_scale).
  template <typename Mismatch>
  static Scalar regula_falsi(Mismatch& mismatch, Scalar a, Scalar b, Scalar fa, Scalar fb, int& used) {
    Scalar fx = fa;
    int side = 0;
    bool bisected = false;
    while (used < kResyncIterations) {
      const bool bisect = far_end(fa, fb);
      bisected = bisected || bisect;
      const Scalar x = bisect ? (a + b) / Scalar(2) : (a * fb - b * fa) / (fb - fa);
      fx = mismatch(x);
      ++used;
      if (!std::isfinite(fx) || std::fabs(fx) < Scalar(kResyncToleranceV)) break;
      if (fx < Scalar(0)) {
        if (side == -1) fb *= retained_scale(bisected, fx, fa);
        a = x; fa = fx;
        side = -1;
      } else {
        if (side == 1) fa *= retained_scale(bisected, fx, fb);
        b = x; fb = fx;
        side = 1;
      }
    }
    return fx;
  }

  // The factor on the mismatch of an end the regula falsi kept twice: Illinois' 1/2, or after a
  // bisection Anderson-Bjorck's 1 - f_new / f_old (1/2 when that is not positive), which cuts
  // harder the less the other end moved. The bracket a far end leaves behind is strongly curved
  // (a shell near its limit) and the halving pulls the secant across too slowly there (the
  // About:Energy probe: 12 evaluations with Illinois, 10 with this). Only after a bisection, so
  // a re-synchronisation that never meets a far end keeps its path (the paper goldens).
  static Scalar retained_scale(bool anderson_bjorck, Scalar f_new, Scalar f_old) {
    if (!anderson_bjorck) return Scalar(0.5);
    const Scalar m = Scalar(1) - f_new / f_old;
    return m > Scalar(0) ? m : Scalar(0.5);
  }

  // An end whose mismatch exceeds kResyncFarEndV is a point where a particle's shell nears its
  // limit, not a guide to the root: the secant point then lands next to the other end and moves
  // it by little, while Illinois halves the far end's mismatch once per evaluation (About:Energy,
  // the board's resync_probe: +273 V against -0.22 V, the root a fifth of the way across; ten of
  // 18 evaluations went to halving). The regula falsi bisects while either end is that far (12).
  static bool far_end(Scalar fa, Scalar fb) {
    return std::fabs(fa) > Scalar(kResyncFarEndV) || std::fabs(fb) > Scalar(kResyncFarEndV);
  }

  // A bracket [a, b] of the re-synchronisation's root near the present state (dn = 0: the model
  // is usually within a few mV of the cell), found by secant steps from 0 that overshoot the
  // predicted root, within [lo, hi]. The regula falsi then starts a few evaluations from its
  // tolerance instead of halving its way in from the whole admissible range (which took 25
  // evaluations). Adds its evaluations to `used`; none_near when no bracket was found (the caller
  // falls back to [lo, hi]). not_monotone when a step towards the root moved the mismatch away
  // from zero: the voltage fell (or stayed) as lithium moved into the anode. The method's
  // premise fails there: both electrodes' open-circuit potentials are flat (LFP against a
  // graphite plateau) and the overpotentials' own dependence on the stoichiometry, opposite in
  // sign, dominates; a root beyond it lies at an electrode's end, where the voltage is matched
  // by a state far from the cell's, and the regula falsi over the whole range spent its cap
  // before reaching it (About:Energy at power-up under 2 A: 40 evaluations, about 400 000
  // instructions on the M7). The caller gives up at once (status kResyncFailed).
  enum class Bracket { found, none_near, not_monotone };
  template <typename Mismatch>
  static Bracket bracket_near(Mismatch& mismatch, Scalar lo, Scalar hi, Scalar& a, Scalar& b, Scalar& fa,
                              Scalar& fb, int& used) {
    if (!(lo < Scalar(0) && hi > Scalar(0))) return Bracket::none_near;
    Scalar x = Scalar(0), fx = mismatch(x);
    ++used;
    if (!std::isfinite(fx)) return Bracket::none_near;
    Scalar step = fx < Scalar(0) ? Scalar(kResyncFirstStep) : Scalar(-kResyncFirstStep);
    for (int n = 1; n <= kResyncBracketSteps; ++n) {
      Scalar xn = x + step;
      xn = xn < lo ? lo : (xn > hi ? hi : xn);
      const Scalar fn = mismatch(xn);
      ++used;
      if (!std::isfinite(fn)) return Bracket::none_near;
      if ((fn < Scalar(0)) != (fx < Scalar(0))) {
        if (fn < Scalar(0)) {
          a = xn; fa = fn; b = x; fb = fx;
        } else {
          a = x; fa = fx; b = xn; fb = fn;
        }
        return Bracket::found;
      }
      const Scalar slope = (fn - fx) / (xn - x);
      if (!(slope > Scalar(0))) return Bracket::not_monotone;
      // Secant prediction of the root from the last two points, overshot so the next point
      // lands beyond it.
      Scalar next = -fn / slope * Scalar(2);
      if (std::fabs(next) < std::fabs(step) * Scalar(2) || (next > Scalar(0)) != (step > Scalar(0))) next = step * Scalar(2);
      x = xn;
      fx = fn;
      step = next;
      if (x == lo || x == hi) return Bracket::none_near;
    }
    return Bracket::none_near;
  }

  // At a re-synchronised state: the voltage's slopes to a uniform shift of each particle, and
  // from them the split (a, b) of one mol of lithium with cap_n a + cap_p b = 1 and
  // V_a a + V_b b = 0 (the voltage the re-synchronisation matched stays matched).
  void set_inventory_direction(Scalar current_a, Scalar r_film_ohm_m2, Scalar dt_s, Scalar v0) {
    const Scalar eps = Scalar(kInventoryProbeStoich);
    ReducedCell probe = *this;
    probe.shift(eps, Scalar(0));
    const Scalar v_a = (probe.peek_voltage(current_a, r_film_ohm_m2, dt_s) - v0) / eps;
    probe = *this;
    probe.shift(Scalar(0), eps);
    const Scalar v_b = (probe.peek_voltage(current_a, r_film_ohm_m2, dt_s) - v0) / eps;
    const Scalar den = Scalar(solid_capacity_neg_mol()) * v_b - Scalar(solid_capacity_pos_mol()) * v_a;
    if (!std::isfinite(den) || den == Scalar(0)) return;
    s_.inventory_dir_neg_per_mol = v_b / den;
    s_.inventory_dir_pos_per_mol = -v_a / den;
  }

  template <typename T>
  struct Trial {
    T d_cs_neg[kNrN];  // changes over the tick (the step's unknowns)
    T d_cs_pos[kNrP];
    T d_ce[kNx];
    T voltage_v;
    T j_side_a_m3;   // volumetric, mean over the anode
    T j_side_a_m2;   // pore-wall, mean over the anode
    T j_neg_a_m2;    // total pore-wall current density of the anode
  };

  static constexpr double a_neg() { return 3.0 * Cell::kNeg.solid_fraction / Cell::kNeg.particle_radius_m; }
  static constexpr double a_pos() { return 3.0 * Cell::kPos.solid_fraction / Cell::kPos.particle_radius_m; }
  static constexpr double solid_capacity_neg_mol() {
    return Cell::kNeg.max_concentration_mol_m3 * Cell::kNeg.solid_fraction * Cell::kNeg.thickness_m * Cell::kAreaM2;
  }
  static constexpr double solid_capacity_pos_mol() {
    return Cell::kPos.max_concentration_mol_m3 * Cell::kPos.solid_fraction * Cell::kPos.thickness_m * Cell::kAreaM2;
  }

  static Scalar mean_shell(const Scalar* c, const Scalar* carry, const Scalar* vol, int n) {
    Scalar sum = Scalar(0), v = Scalar(0);
    for (int i = 0; i < n; ++i) {
      sum += (c[i] + carry[i]) * vol[i];
      v += vol[i];
    }
    return sum / v;
  }

  void clear_carries() {
    for (int i = 0; i < kNrN; ++i) s_.cs_neg_carry_mol_m3[i] = Scalar(0);
    for (int i = 0; i < kNrP; ++i) s_.cs_pos_carry_mol_m3[i] = Scalar(0);
    for (int k = 0; k < kNx; ++k) s_.ce_carry_mol_m3[k] = Scalar(0);
    s_.li_loss_carry_mol = Scalar(0);
  }

  // value + carry += increment, keeping in carry what value cannot hold (Kahan).
  static void add_compensated(Scalar& value, Scalar& carry, Scalar increment) {
    const Scalar y = increment + carry;
    const Scalar sum = value + y;
    carry = y - (sum - value);
    value = sum;
  }

  // Diffusive exchange of cell i with its neighbours at the start of the tick, sum over the
  // faces of g (c_i - c_j), from the differences of the stored values and of their carries.
  template <int N>
  static Scalar outflow(const Scalar (&c)[N], const Scalar (&carry)[N], const Scalar (&g)[N], int i) {
    Scalar out = Scalar(0);
    if (i > 0) out += g[i - 1] * ((c[i] - c[i - 1]) + (carry[i] - carry[i - 1]));
    if (i + 1 < N) out += g[i] * ((c[i] - c[i + 1]) + (carry[i] - carry[i + 1]));
    return out;
  }

  static void shells(double radius, int n, Scalar* vol, Scalar* cond_r2_over_d, Scalar& outer_r2,
                     Scalar& surface_half) {
    // Face i at R f(i/n), f(s) = s + b s (1 - s): finer shells towards the surface.
    double face[16 + 1];
    for (int i = 0; i <= n; ++i) {
      const double u = static_cast<double>(i) / n;
      face[i] = radius * (u + kSurfaceRefinement * u * (1.0 - u));
    }
    for (int i = 0; i < n; ++i) vol[i] = Scalar((face[i + 1] * face[i + 1] * face[i + 1] - face[i] * face[i] * face[i]) / 3.0);
    for (int i = 0; i + 1 < n; ++i) {
      const double dist = 0.5 * (face[i + 2] - face[i]);
      cond_r2_over_d[i] = Scalar(face[i + 1] * face[i + 1] / dist);
    }
    outer_r2 = Scalar(face[n] * face[n]);
    surface_half = Scalar(0.5 * (face[n] - face[n - 1]));
  }

  // eps^b with the cell's Bruggeman exponent, or (a cell generated from a BPX file, which gives
  // the transport efficiency of each region) the region's own value.
  template <class C, class = void>
  struct HasRegionTransport : std::false_type {};
  template <class C>
  struct HasRegionTransport<C, std::void_t<decltype(C::kTransportEfficiencyNeg)>> : std::true_type {};
  static double transport_efficiency(int k, double eps) {
    if constexpr (HasRegionTransport<Cell>::value) {
      return k < kNn ? Cell::kTransportEfficiencyNeg
                     : (k < kNn + kNs ? Cell::kTransportEfficiencySep : Cell::kTransportEfficiencyPos);
    } else {
      return std::pow(eps, Cell::kBruggeman);
    }
  }

  void build_geometry() {
    static_assert(kNrN <= 16 && kNrP <= 16, "at most 16 shells per particle");
    shells(Cell::kNeg.particle_radius_m, kNrN, vol_n_, g_n_, r2_n_, half_n_);
    shells(Cell::kPos.particle_radius_m, kNrP, vol_p_, g_p_, r2_p_, half_p_);
    for (int k = 0; k < kNx; ++k) {
      double dx, eps, a;
      if (k < kNn) {
        dx = Cell::kNeg.thickness_m / kNn; eps = Cell::kNeg.porosity; a = a_neg();
      } else if (k < kNn + kNs) {
        dx = Cell::kSeparatorThicknessM / kNs; eps = Cell::kSeparatorPorosity; a = 0.0;
      } else {
        dx = Cell::kPos.thickness_m / kNp; eps = Cell::kPos.porosity; a = a_pos();
      }
      dx_[k] = Scalar(dx);
      eps_[k] = Scalar(eps);
      te_[k] = Scalar(transport_efficiency(k, eps));
      a_[k] = Scalar(a);
    }
  }

  // Solves the chain system in place: rhs -> x. g[i] couples i and i+1.
  template <typename T, int N>
  static void chain_solve(const Scalar (&m)[N], const Scalar (&g)[N], T (&x)[N]) {
    Scalar cp[N];
    Scalar dd[N];
    for (int i = 0; i < N; ++i) {
      const Scalar gl = i > 0 ? g[i - 1] : Scalar(0);
      const Scalar gr = i + 1 < N ? g[i] : Scalar(0);
      dd[i] = m[i] + gl + gr;
      if (i > 0) {
        dd[i] -= gl * cp[i - 1];
        x[i] = x[i] + gl * x[i - 1] / dd[i - 1];
      }
      cp[i] = gr / dd[i];
    }
    x[N - 1] = x[N - 1] / dd[N - 1];
    for (int i = N - 2; i >= 0; --i) x[i] = x[i] / dd[i] + cp[i] * x[i + 1];
  }

  // Backward-Euler particle step with molar flux out of the surface `flux_out` [mol/m2/s], in
  // increments: (M + G) dc = -G c_old - flux term; returns the surface concentration.
  template <typename T, int N>
  static T particle_step(const Scalar (&c_old)[N], const Scalar (&carry)[N], const Scalar (&vol)[N],
                         const Scalar* g_r2_d, Scalar outer_r2, Scalar surface_half, Scalar ds, Scalar dt,
                         const T& flux_out, T (&dc)[N]) {
    Scalar m[N], g[N];
    for (int i = 0; i < N; ++i) {
      m[i] = vol[i] / dt;
      g[i] = i + 1 < N ? g_r2_d[i] * ds : Scalar(0);
    }
    for (int i = 0; i < N; ++i) dc[i] = T(-outflow(c_old, carry, g, i));
    dc[N - 1] = dc[N - 1] - outer_r2 * flux_out;
    chain_solve(m, g, dc);
    return (dc[N - 1] + (c_old[N - 1] + carry[N - 1])) - surface_half * flux_out / ds;
  }

  template <typename T>
  static T asinh_of(const T& x) {
    using std::log; using std::sqrt;
    // Sign-symmetric form: accurate for large negative x as well.
    if (value_of(x) >= Scalar(0)) return log(x + sqrt(x * x + Scalar(1)));
    return -log(-x + sqrt(x * x + Scalar(1)));
  }

  template <typename T>
  static T clamp_conc(const T& c, double cmax) {
    const Scalar lo = Scalar(1e-6 * cmax), hi = Scalar((1.0 - 1e-6) * cmax);
    if (value_of(c) < lo) return T(lo);
    if (value_of(c) > hi) return T(hi);
    return c;
  }

  template <typename T>
  void evaluate(const T& current_a, Scalar r_film, Scalar dt, Trial<T>& t) const {
    const Scalar frt = frt_;
    const T i_app = current_a / Scalar(Cell::kAreaM2);  // A/m2, positive = discharge
    const T j_n = i_app / Scalar(a_neg() * Cell::kNeg.thickness_m);
    const T j_p = -i_app / Scalar(a_pos() * Cell::kPos.thickness_m);
    T ce[kNx];
    electrolyte_concentration(j_n, j_p, dt, t, ce);
    T phie[kNx];
    electrolyte_potential(ce, j_n, j_p, frt, phie);
    T phis_n = T(Scalar(0));
    T js = T(s_.j_side_a_m2);
    negative_electrode(ce, phie, j_n, r_film, dt, frt, t, phis_n, js);
    const T phis_p = positive_electrode(ce, phie, j_p, dt, frt, t);

    // Solid ohmic drop with a uniform reaction: mean potential to current collector is I L/(3 sigma).
    const T ohmic = i_app * Scalar(Cell::kNeg.thickness_m / (3.0 * Cell::kNeg.conductivity_eff_s_m) +
                                   Cell::kPos.thickness_m / (3.0 * Cell::kPos.conductivity_eff_s_m));
    t.voltage_v = phis_p - phis_n - ohmic;
    t.j_side_a_m2 = js;
    t.j_side_a_m3 = js * Scalar(a_neg());
    t.j_neg_a_m2 = j_n;
  }

  // evaluate()'s four parts are inlined by force: called as functions they cost 2.6 % more
  // instructions per tick on the Cortex-M7 (worst tick 114 200 against 111 280 in one body).
  // Electrolyte concentration: D_e at the start of the tick, source from the uniform j.
  template <typename T>
  [[gnu::always_inline]] inline void electrolyte_concentration(const T& j_n, const T& j_p, Scalar dt, Trial<T>& t,
                                                               T (&ce)[kNx]) const {
    Scalar m[kNx], g[kNx];
    Scalar d_eff[kNx];
    for (int k = 0; k < kNx; ++k) {
      d_eff[k] = Cell::electrolyte_diffusivity_m2_s(s_.ce_mol_m3[k]) * te_de_[k];
    }
    for (int k = 0; k < kNx; ++k) {
      m[k] = eps_[k] * dx_[k] / dt;
      g[k] = k + 1 < kNx ? Scalar(1) / (dx_[k] / (Scalar(2) * d_eff[k]) + dx_[k + 1] / (Scalar(2) * d_eff[k + 1]))
                         : Scalar(0);
    }
    for (int k = 0; k < kNx; ++k) {
      const T j_k = k < kNn ? j_n : (k < kNn + kNs ? T(Scalar(0)) : j_p);
      t.d_ce[k] = Scalar((1.0 - Cell::kTransference) / kFaradayC_mol) * a_[k] * j_k * dx_[k] -
                  outflow(s_.ce_mol_m3, s_.ce_carry_mol_m3, g, k);
    }
    chain_solve(m, g, t.d_ce);
    for (int k = 0; k < kNx; ++k) ce[k] = t.d_ce[k] + (s_.ce_mol_m3[k] + s_.ce_carry_mol_m3[k]);
  }

  // Electrolyte potential at cell centres from the ionic current on the faces
  // (psi = phi_e - nu ln c_e, reference psi_0 = 0).
  template <typename T>
  [[gnu::always_inline]] inline void electrolyte_potential(const T (&ce)[kNx], const T& j_n, const T& j_p, Scalar frt,
                                                           T (&phie)[kNx]) const {
    using std::log;
    const Scalar nu = Scalar(2.0 * (1.0 - Cell::kTransference)) / frt;
    T psi = T(Scalar(0));
    T ie = T(Scalar(0));
    T kap_k = Cell::electrolyte_conductivity_s_m(clamp_low(ce[0])) * te_ke_[0];
    phie[0] = nu * log(clamp_low(ce[0]));
    for (int k = 0; k + 1 < kNx; ++k) {
      const T j_k = k < kNn ? j_n : (k < kNn + kNs ? T(Scalar(0)) : j_p);
      ie = ie + a_[k] * j_k * dx_[k];
      const T kap_n = Cell::electrolyte_conductivity_s_m(clamp_low(ce[k + 1])) * te_ke_[k + 1];
      const T rk = dx_[k] / (Scalar(2) * kap_k) + dx_[k + 1] / (Scalar(2) * kap_n);
      psi = psi - ie * rk;
      phie[k + 1] = psi + nu * log(clamp_low(ce[k + 1]));
      kap_k = kap_n;
    }
  }

  // Negative electrode: side reaction inside Butler-Volmer, fixed number of passes. js enters
  // with the previous tick's side current density and leaves with this tick's.
  template <typename T>
  [[gnu::always_inline]] inline void negative_electrode(const T (&ce)[kNx], const T (&phie)[kNx], const T& j_n,
                                                        Scalar r_film, Scalar dt, Scalar frt, Trial<T>& t, T& phis_n,
                                                        T& js) const {
    using std::exp; using std::sqrt;
    const double cmax_n = Cell::kNeg.max_concentration_mol_m3;
    T cs_surf_n = T(Scalar(0));
    for (int pass = 0; pass <= kSidePasses; ++pass) {
      const T flux_out = (j_n - js) / Scalar(kFaradayC_mol);
      cs_surf_n = clamp_conc(particle_step(s_.cs_neg_mol_m3, s_.cs_neg_carry_mol_m3, vol_n_, g_n_, r2_n_, half_n_,
                                           ds_neg_, dt, flux_out, t.d_cs_neg),
                             cmax_n);
      T ocp = Cell::ocp_neg_v(cs_surf_n / Scalar(cmax_n));
      if constexpr (TemperatureData::kHasEntropic)
        ocp = ocp + d_temperature_k_ * TemperatureData::entropic_neg_v_k(cs_surf_n / Scalar(cmax_n));
      T js_sum = T(Scalar(0));
      phis_n = T(Scalar(0));
      for (int k = 0; k < kNn; ++k) {
        const T i0 = i0_coef_neg_ * sqrt(clamp_low(ce[k]) * cs_surf_n * (Scalar(cmax_n) - cs_surf_n));
        const T eta = Scalar(2) / frt * asinh_of((j_n - js) / (Scalar(2) * i0));
        phis_n = phis_n + phie[k] + ocp + eta + j_n * r_film;
        T arg = Scalar(-Cell::kSideAlpha) * frt * (eta + ocp - Scalar(Cell::kSideRefPotentialV));
        if (value_of(arg) > Scalar(60)) arg = T(Scalar(60));
        if (value_of(arg) < Scalar(-60)) arg = T(Scalar(-60));
        js_sum = js_sum - side_exchange_a_m2_ * exp(arg);
      }
      phis_n = phis_n / Scalar(kNn);
      js = js_sum / Scalar(kNn);
    }
  }

  template <typename T>
  [[gnu::always_inline]] inline T positive_electrode(const T (&ce)[kNx], const T (&phie)[kNx], const T& j_p, Scalar dt,
                                                     Scalar frt, Trial<T>& t) const {
    using std::sqrt;
    const double cmax_p = Cell::kPos.max_concentration_mol_m3;
    const T cs_surf_p = clamp_conc(
        particle_step(s_.cs_pos_mol_m3, s_.cs_pos_carry_mol_m3, vol_p_, g_p_, r2_p_, half_p_,
                      ds_pos_, dt, T(j_p / Scalar(kFaradayC_mol)), t.d_cs_pos),
        cmax_p);
    T ocp_p = Cell::ocp_pos_v(cs_surf_p / Scalar(cmax_p));
    if constexpr (TemperatureData::kHasEntropic)
      ocp_p = ocp_p + d_temperature_k_ * TemperatureData::entropic_pos_v_k(cs_surf_p / Scalar(cmax_p));
    T phis_p = T(Scalar(0));
    for (int k = kNn + kNs; k < kNx; ++k) {
      const T i0 = i0_coef_pos_ * sqrt(clamp_low(ce[k]) * cs_surf_p * (Scalar(cmax_p) - cs_surf_p));
      phis_p = phis_p + phie[k] + ocp_p + Scalar(2) / frt * asinh_of(j_p / (Scalar(2) * i0));
    }
    return phis_p / Scalar(kNp);
  }

  // s / (1 - s): a property inversely proportional to a parameter at (1 - s) of it, relative.
  static Scalar spread_inverse(Scalar s) {
    return s > Scalar(0) && s < Scalar(1) ? s / (Scalar(1) - s) : Scalar(0);
  }

  // Mean over the cells [k0, k1) of 2/f (asinh(j / 2 i0 (1 - s)) - asinh(j / 2 i0)) [V], |.|.
  Scalar kinetic_spread_v(const Scalar (&ce)[kNx], int k0, int k1, Scalar i0_coef, Scalar cs, double cmax, Scalar j,
                          Scalar s) const {
    if (!(s > Scalar(0) && s < Scalar(1))) return Scalar(0);
    Scalar sum = Scalar(0);
    for (int k = k0; k < k1; ++k) {
      const Scalar x = j / (Scalar(2) * i0_coef * std::sqrt(ce[k] * cs * (Scalar(cmax) - cs)));
      sum += asinh_of(x / (Scalar(1) - s)) - asinh_of(x);
    }
    return std::fabs(Scalar(2) / frt_ * sum / Scalar(k1 - k0));
  }

  // The electrolyte's ohmic drop and concentration overpotential between the mean of the cathode's
  // cells and the mean of the anode's [V], |.| (electrolyte_potential's split of phi_e).
  void electrolyte_drops(const Scalar (&ce)[kNx], Scalar j_n, Scalar j_p, Scalar& ohmic_v, Scalar& conc_v) const {
    const Scalar nu = Scalar(2.0 * (1.0 - Cell::kTransference)) / frt_;
    Scalar psi = Scalar(0), ie = Scalar(0), psi_n = Scalar(0), psi_p = Scalar(0), ln_n = Scalar(0), ln_p = Scalar(0);
    Scalar kap_k = Cell::electrolyte_conductivity_s_m(ce[0]) * te_ke_[0];
    for (int k = 0; k < kNx; ++k) {
      if (k > 0) {
        const Scalar j_k = k - 1 < kNn ? j_n : (k - 1 < kNn + kNs ? Scalar(0) : j_p);
        ie += a_[k - 1] * j_k * dx_[k - 1];
        const Scalar kap_n = Cell::electrolyte_conductivity_s_m(ce[k]) * te_ke_[k];
        psi -= ie * (dx_[k - 1] / (Scalar(2) * kap_k) + dx_[k] / (Scalar(2) * kap_n));
        kap_k = kap_n;
      }
      if (k < kNn) psi_n += psi, ln_n += std::log(ce[k]);
      if (k >= kNn + kNs) psi_p += psi, ln_p += std::log(ce[k]);
    }
    ohmic_v = std::fabs(psi_p / Scalar(kNp) - psi_n / Scalar(kNn));
    conc_v = std::fabs(nu * (ln_p / Scalar(kNp) - ln_n / Scalar(kNn)));
  }

  template <typename T>
  static T clamp_low(const T& c) {
    return value_of(c) < Scalar(1e-3) ? T(Scalar(1e-3)) : c;
  }

  // exp(E/R (1/T_ref - 1/T)) from ratio = T_ref / T: exactly 1 at T_ref and for E = 0.
  static Scalar arrhenius(double activation_j_mol, Scalar ratio) {
    if (activation_j_mol == 0.0) return Scalar(1);
    using std::exp;
    return exp(Scalar(activation_j_mol / (kGasJ_molK * TemperatureData::kReferenceK)) * (Scalar(1) - ratio));
  }

  void apply_temperature(Scalar t_k) {
    using TD = TemperatureData;
    temperature_k_ = t_k;
    d_temperature_k_ = t_k - Scalar(TD::kReferenceK);
    const Scalar ratio = Scalar(TD::kReferenceK) / t_k;
    frt_ = Scalar(kFaradayC_mol / (kGasJ_molK * TD::kReferenceK)) * ratio;
    ds_neg_ = Scalar(Cell::kNeg.solid_diffusivity_m2_s) * arrhenius(TD::kNegDiffusivityActivationJMol, ratio);
    ds_pos_ = Scalar(Cell::kPos.solid_diffusivity_m2_s) * arrhenius(TD::kPosDiffusivityActivationJMol, ratio);
    i0_coef_neg_ = Scalar(Cell::kNeg.i0_coefficient) * arrhenius(TD::kNegRateActivationJMol, ratio);
    i0_coef_pos_ = Scalar(Cell::kPos.i0_coefficient) * arrhenius(TD::kPosRateActivationJMol, ratio);
    side_exchange_a_m2_ = Scalar(Cell::kSideExchangeAM2) * arrhenius(TD::kSideActivationJMol, ratio);
    const Scalar arr_de = arrhenius(TD::kElectrolyteDiffusivityActivationJMol, ratio);
    const Scalar arr_ke = arrhenius(TD::kElectrolyteConductivityActivationJMol, ratio);
    for (int k = 0; k < kNx; ++k) {
      te_de_[k] = te_[k] * arr_de;
      te_ke_[k] = te_[k] * arr_ke;
    }
  }

  bool commit(const Trial<Scalar>& t, Scalar current_a, Scalar dt) {
    bool ok = std::isfinite(t.voltage_v) && std::isfinite(t.j_side_a_m2);
    for (int i = 0; ok && i < kNrN; ++i) ok = std::isfinite(t.d_cs_neg[i]);
    for (int i = 0; ok && i < kNrP; ++i) ok = std::isfinite(t.d_cs_pos[i]);
    for (int k = 0; ok && k < kNx; ++k) ok = std::isfinite(t.d_ce[k]);
    if (!ok) return false;
    for (int i = 0; i < kNrN; ++i) add_compensated(s_.cs_neg_mol_m3[i], s_.cs_neg_carry_mol_m3[i], t.d_cs_neg[i]);
    for (int i = 0; i < kNrP; ++i) add_compensated(s_.cs_pos_mol_m3[i], s_.cs_pos_carry_mol_m3[i], t.d_cs_pos[i]);
    for (int k = 0; k < kNx; ++k) add_compensated(s_.ce_mol_m3[k], s_.ce_carry_mol_m3[k], t.d_ce[k]);
    // Lithium consumed by the side reaction over the anode (j_s < 0 consumes): a sum that
    // grows over the cell's life while each tick adds about 1e-10 mol.
    add_compensated(s_.li_loss_mol, s_.li_loss_carry_mol,
                    -t.j_side_a_m2 * Scalar(a_neg() * Cell::kNeg.thickness_m * Cell::kAreaM2 / kFaradayC_mol) * dt);
    s_.charge_c += current_a * dt;
    s_.current_a = current_a;
    s_.j_side_a_m2 = t.j_side_a_m2;
    return true;
  }

  State s_{};
  Scalar vol_n_[kNrN]{}, g_n_[kNrN]{}, vol_p_[kNrP]{}, g_p_[kNrP]{};
  Scalar r2_n_ = Scalar(0), half_n_ = Scalar(0), r2_p_ = Scalar(0), half_p_ = Scalar(0);
  Scalar dx_[kNx]{}, eps_[kNx]{}, te_[kNx]{}, a_[kNx]{};
  // At the temperature in use (apply_temperature): transport efficiency times the electrolyte's
  // Arrhenius factors, solid diffusivities, reaction-rate coefficients, side exchange current.
  Scalar te_de_[kNx]{}, te_ke_[kNx]{};
  Scalar temperature_k_ = Scalar(0), d_temperature_k_ = Scalar(0), frt_ = Scalar(0);
  Scalar ds_neg_ = Scalar(0), ds_pos_ = Scalar(0), i0_coef_neg_ = Scalar(0), i0_coef_pos_ = Scalar(0);
  Scalar side_exchange_a_m2_ = Scalar(0);
  int resync_evaluations_ = 0;
};

}  // namespace bms::fw
