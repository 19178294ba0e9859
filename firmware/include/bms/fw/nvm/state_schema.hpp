// Schema hashes of the state images saved to non-volatile memory.
//
// A record's layout tag used to encode only sizes, so an image of a firmware whose state
// had two fields swapped, renamed or retyped (same size) was restored into the wrong
// fields. The tag is now a hash (FNV-1a, 32 bits) of the schema: every field's name, type
// (kind and size of a number, element type and count of an array, the nested schema of a
// struct), offset and size, in declaration order, and the struct's size.
//
// The tables below name every field of every saved struct; the compiler keeps them true:
// offsetof() fails on a renamed or removed field, decltype() sees a retyped one, and
// covers() (a static_assert) fails when a field was added (the struct is bigger than what
// the table describes) or reordered (offsets no longer ascend).
//
// To save another model type with BmsCore, add a state_schema() overload for it here (or
// beside the type: it is found by argument-dependent lookup through Type<Model>).
//
// Header-only C++17: no heap, no exceptions, no RTTI.
#pragma once

#include <cstddef>
#include <cstdint>
#include <type_traits>

#include "bms/fw/estimation/bias_calibration.hpp"
#include "bms/fw/estimation/bms_core.hpp"
#include "bms/fw/estimation/area_scale.hpp"
#include "bms/fw/estimation/current_offset.hpp"
#include "bms/fw/estimation/voltage_offset.hpp"
#include "bms/fw/model/cell_effects.hpp"
#include "bms/fw/estimation/film_growth_identifier.hpp"
#include "bms/fw/estimation/film_level.hpp"
#include "bms/fw/estimation/identifier_film_path.hpp"
#include "bms/fw/estimation/learning_gate.hpp"
#include "bms/fw/estimation/mode_detector.hpp"
#include "bms/fw/estimation/rcsi_estimator.hpp"
#include "bms/fw/estimation/rcsi_film_path.hpp"
#include "bms/fw/model/reduced_cell.hpp"
#include "bms/fw/estimation/resync_window.hpp"
#include "bms/fw/estimation/rls.hpp"
#include "bms/fw/estimation/state_resync.hpp"

namespace bms::fw::schema {

struct Field {
  const char* name;
  std::uint32_t type;  ///< type hash (type_hash<T>() or a nested schema hash)
  std::size_t offset;
  std::size_t size;
};

/// A tag type that selects the state_schema() overload of an owner class.
template <class T>
struct Type {};

inline constexpr std::uint32_t kFnvBasis = 2166136261u;
inline constexpr std::uint32_t kFnvPrime = 16777619u;

constexpr std::uint32_t fnv_byte(std::uint32_t h, std::uint8_t b) { return (h ^ b) * kFnvPrime; }
constexpr std::uint32_t fnv_text(std::uint32_t h, const char* s) {
  for (; *s != '\0'; ++s) h = fnv_byte(h, static_cast<std::uint8_t>(*s));
  return fnv_byte(h, 0u);  // terminator: "ab"+"c" differs from "a"+"bc"
}
constexpr std::uint32_t fnv_number(std::uint32_t h, std::uint64_t v) {
  for (unsigned i = 0; i < 8u; ++i) h = fnv_byte(h, static_cast<std::uint8_t>((v >> (8u * i)) & 0xFFu));
  return h;
}

/// Hash of a number or array-of-numbers type: its kind (f, i, u, b), size and extent.
template <class T>
constexpr std::uint32_t type_hash() {
  if constexpr (std::is_array<T>::value) {
    return fnv_number(type_hash<std::remove_extent_t<T>>(), std::extent<T>::value);
  } else {
    static_assert(std::is_arithmetic<T>::value, "a struct member needs BMS_SCHEMA_NESTED");
    const char kind = std::is_same<T, bool>::value ? 'b'
                      : std::is_floating_point<T>::value ? 'f'
                      : std::is_signed<T>::value ? 'i'
                                                 : 'u';
    return fnv_number(fnv_byte(kFnvBasis, static_cast<std::uint8_t>(kind)), sizeof(T));
  }
}

template <std::size_t N>
constexpr std::uint32_t hash(const char* struct_name, const Field (&fields)[N], std::size_t struct_size) {
  std::uint32_t h = fnv_number(fnv_text(kFnvBasis, struct_name), struct_size);
  for (const Field& f : fields) {
    h = fnv_text(h, f.name);
    h = fnv_number(h, f.type);
    h = fnv_number(h, f.offset);
    h = fnv_number(h, f.size);
  }
  return h;
}

/// True when the fields follow each other in declaration order and leave nothing of the
/// struct undescribed but padding (a gap smaller than the struct's alignment).
template <std::size_t N>
constexpr bool covers(const Field (&fields)[N], std::size_t struct_size, std::size_t align) {
  std::size_t end = 0;
  for (const Field& f : fields) {
    if (f.offset < end || f.offset - end >= align) return false;
    end = f.offset + f.size;
  }
  return end <= struct_size && struct_size - end < align;
}

// NOLINTBEGIN(cppcoreguidelines-macro-usage): offsetof and the member's name need a macro.
#define BMS_SCHEMA_FIELD(S, member) \
  ::bms::fw::schema::Field { #member, ::bms::fw::schema::type_hash<decltype(S::member)>(), offsetof(S, member), sizeof(S::member) }
#define BMS_SCHEMA_NESTED(S, member, owner) \
  ::bms::fw::schema::Field { #member, state_schema(::bms::fw::schema::Type<owner>{}), offsetof(S, member), sizeof(S::member) }
// NOLINTEND(cppcoreguidelines-macro-usage)

template <class S, int N>
constexpr std::uint32_t state_schema(Type<Rls<S, N>> /*tag*/) {
  using St = typename Rls<S, N>::State;
  constexpr Field f[] = {BMS_SCHEMA_FIELD(St, theta), BMS_SCHEMA_FIELD(St, p)};
  static_assert(covers(f, sizeof(St), alignof(St)), "Rls::State changed: update its schema table");
  return hash("Rls.State", f, sizeof(St));
}

template <class S>
constexpr std::uint32_t state_schema(Type<FilmGrowthIdentifier<S>> /*tag*/) {
  using St = typename FilmGrowthIdentifier<S>::State;
  constexpr Field f[] = {BMS_SCHEMA_NESTED(St, rls, typename FilmGrowthIdentifier<S>::RlsType),
                         BMS_SCHEMA_FIELD(St, growth_ohm_m2), BMS_SCHEMA_FIELD(St, growth_at_charge_ohm_m2),
                         BMS_SCHEMA_FIELD(St, growth_carry_ohm_m2)};
  static_assert(covers(f, sizeof(St), alignof(St)), "FilmGrowthIdentifier::State changed: update its schema table");
  return hash("FilmGrowthIdentifier.State", f, sizeof(St));
}

template <class S>
constexpr std::uint32_t state_schema(Type<ModeDetector<S>> /*tag*/) {
  using St = typename ModeDetector<S>::State;
  constexpr Field f[] = {BMS_SCHEMA_FIELD(St, mode), BMS_SCHEMA_FIELD(St, candidate),
                         BMS_SCHEMA_FIELD(St, candidate_ticks), BMS_SCHEMA_FIELD(St, reserved),
                         BMS_SCHEMA_FIELD(St, cc_level_a)};
  static_assert(covers(f, sizeof(St), alignof(St)), "ModeDetector::State changed: update its schema table");
  return hash("ModeDetector.State", f, sizeof(St));
}

template <class S, int Nc, int D>
constexpr std::uint32_t state_schema(Type<RcsiEstimator<S, Nc, D>> /*tag*/) {
  using E = RcsiEstimator<S, Nc, D>;
  using St = typename E::State;
  constexpr Field f[] = {BMS_SCHEMA_FIELD(St, layout_tag),         BMS_SCHEMA_FIELD(St, flags),
                         BMS_SCHEMA_FIELD(St, ticks),              BMS_SCHEMA_FIELD(St, status),
                         BMS_SCHEMA_FIELD(St, tick_status),        BMS_SCHEMA_FIELD(St, reserved),
                         BMS_SCHEMA_FIELD(St, markov_v_per_ohm_m2), BMS_SCHEMA_FIELD(St, u_hat_ohm_m2),
                         BMS_SCHEMA_FIELD(St, u_star_ohm_m2),      BMS_SCHEMA_NESTED(St, rls, typename E::RlsType),
                         BMS_SCHEMA_FIELD(St, phi_history)};
  static_assert(covers(f, sizeof(St), alignof(St)), "RcsiEstimator::State changed: update its schema table");
  return hash("RcsiEstimator.State", f, sizeof(St));
}

template <class S>
constexpr std::uint32_t state_schema(Type<ResyncWindow<S>> /*tag*/) {
  using St = typename ResyncWindow<S>::State;
  constexpr Field f[] = {BMS_SCHEMA_FIELD(St, samples), BMS_SCHEMA_FIELD(St, length), BMS_SCHEMA_FIELD(St, v0_v),
                         BMS_SCHEMA_FIELD(St, i0_a),    BMS_SCHEMA_FIELD(St, sum_x),  BMS_SCHEMA_FIELD(St, sum_xx),
                         BMS_SCHEMA_FIELD(St, sum_v),   BMS_SCHEMA_FIELD(St, sum_xv), BMS_SCHEMA_FIELD(St, sum_i),
                         BMS_SCHEMA_FIELD(St, sum_xi)};
  static_assert(covers(f, sizeof(St), alignof(St)), "ResyncWindow::State changed: update its schema table");
  return hash("ResyncWindow.State", f, sizeof(St));
}

template <class S>
constexpr std::uint32_t state_schema(Type<LearningGate<S>> /*tag*/) {
  using St = typename LearningGate<S>::State;
  constexpr Field f[] = {BMS_SCHEMA_FIELD(St, cc_ticks), BMS_SCHEMA_FIELD(St, flags)};
  static_assert(covers(f, sizeof(St), alignof(St)), "LearningGate::State changed: update its schema table");
  return hash("LearningGate.State", f, sizeof(St));
}

template <class S>
constexpr std::uint32_t state_schema(Type<BiasCalibration<S>> /*tag*/) {
  using St = typename BiasCalibration<S>::State;
  constexpr Field f[] = {BMS_SCHEMA_FIELD(St, sum_v), BMS_SCHEMA_FIELD(St, bias_v), BMS_SCHEMA_FIELD(St, samples),
                         BMS_SCHEMA_FIELD(St, calibrated)};
  static_assert(covers(f, sizeof(St), alignof(St)), "BiasCalibration::State changed: update its schema table");
  return hash("BiasCalibration.State", f, sizeof(St));
}

template <class S>
constexpr std::uint32_t state_schema(Type<FilmLevel<S>> /*tag*/) {
  using St = typename FilmLevel<S>::State;
  constexpr Field f[] = {BMS_SCHEMA_FIELD(St, r_held_ohm_m2), BMS_SCHEMA_FIELD(St, growth_ohm_m2),
                         BMS_SCHEMA_FIELD(St, avg_sum_ohm_m2), BMS_SCHEMA_FIELD(St, avg_samples),
                         BMS_SCHEMA_FIELD(St, reserved)};
  static_assert(covers(f, sizeof(St), alignof(St)), "FilmLevel::State changed: update its schema table");
  return hash("FilmLevel.State", f, sizeof(St));
}

template <class S>
constexpr std::uint32_t state_schema(Type<StateResync<S>> /*tag*/) {
  using St = typename StateResync<S>::State;
  constexpr Field f[] = {BMS_SCHEMA_NESTED(St, window, ResyncWindow<S>), BMS_SCHEMA_FIELD(St, inventory_deviation_model),
                         BMS_SCHEMA_FIELD(St, count), BMS_SCHEMA_FIELD(St, flags)};
  static_assert(covers(f, sizeof(St), alignof(St)), "StateResync::State changed: update its schema table");
  return hash("StateResync.State", f, sizeof(St));
}

template <class S>
constexpr std::uint32_t state_schema(Type<CurrentOffset<S>> /*tag*/) {
  using St = typename CurrentOffset<S>::State;
  constexpr Field f[] = {BMS_SCHEMA_FIELD(St, charge_as),      BMS_SCHEMA_FIELD(St, span_s),
                         BMS_SCHEMA_FIELD(St, anchor_voltage_v), BMS_SCHEMA_FIELD(St, offset_a),
                         BMS_SCHEMA_FIELD(St, last_current_a), BMS_SCHEMA_FIELD(St, fused),
                         BMS_SCHEMA_FIELD(St, flags)};
  static_assert(covers(f, sizeof(St), alignof(St)), "CurrentOffset::State changed: update its schema table");
  return hash("CurrentOffset.State", f, sizeof(St));
}

template <class S>
constexpr std::uint32_t state_schema(Type<VoltageOffset<S>> /*tag*/) {
  using St = typename VoltageOffset<S>::State;
  constexpr Field f[] = {BMS_SCHEMA_FIELD(St, sum_z_v),      BMS_SCHEMA_FIELD(St, sum_w),
                         BMS_SCHEMA_FIELD(St, offset_v),     BMS_SCHEMA_FIELD(St, charge_markov_v_per_ohm_m2),
                         BMS_SCHEMA_FIELD(St, phase_s),      BMS_SCHEMA_FIELD(St, ticks),
                         BMS_SCHEMA_FIELD(St, fitted_ticks), BMS_SCHEMA_FIELD(St, fused),
                         BMS_SCHEMA_FIELD(St, flags)};
  static_assert(covers(f, sizeof(St), alignof(St)), "VoltageOffset::State changed: update its schema table");
  return hash("VoltageOffset.State", f, sizeof(St));
}

/// A generated cell configuration (bms/fw/cells/) carries its record's CRC: the state of a model
/// of that cell is tagged with it, so that a state saved under one cell is refused under another
/// (same layout, other numbers). The paper cell's traits carry none: its tag is unchanged.
template <class Cell, class = void>
struct CellIdentity {
  static constexpr std::uint32_t mix(std::uint32_t h) { return h; }
};
template <class Cell>
struct CellIdentity<Cell, std::void_t<decltype(Cell::kRecordCrc32)>> {
  static constexpr std::uint32_t mix(std::uint32_t h) { return fnv_number(h, Cell::kRecordCrc32); }
};

template <class S, class Cell, class Mesh>
constexpr std::uint32_t state_schema(Type<ReducedCell<S, Cell, Mesh>> /*tag*/) {
  using St = typename ReducedCell<S, Cell, Mesh>::State;
  constexpr Field f[] = {BMS_SCHEMA_FIELD(St, cs_neg_mol_m3),
                         BMS_SCHEMA_FIELD(St, cs_pos_mol_m3),
                         BMS_SCHEMA_FIELD(St, ce_mol_m3),
                         BMS_SCHEMA_FIELD(St, li_loss_mol),
                         BMS_SCHEMA_FIELD(St, charge_c),
                         BMS_SCHEMA_FIELD(St, current_a),
                         BMS_SCHEMA_FIELD(St, j_side_a_m2),
                         BMS_SCHEMA_FIELD(St, inventory_dir_neg_per_mol),
                         BMS_SCHEMA_FIELD(St, inventory_dir_pos_per_mol),
                         BMS_SCHEMA_FIELD(St, cs_neg_carry_mol_m3),
                         BMS_SCHEMA_FIELD(St, cs_pos_carry_mol_m3),
                         BMS_SCHEMA_FIELD(St, ce_carry_mol_m3),
                         BMS_SCHEMA_FIELD(St, li_loss_carry_mol)};
  static_assert(covers(f, sizeof(St), alignof(St)), "ReducedCell::State changed: update its schema table");
  return CellIdentity<Cell>::mix(hash("ReducedCell.State", f, sizeof(St)));
}

template <class Inner, unsigned Effects>
constexpr std::uint32_t state_schema(Type<EffectsModel<Inner, Effects>> /*tag*/) {
  using St = typename EffectsModel<Inner, Effects>::State;
  constexpr Field f[] = {BMS_SCHEMA_NESTED(St, inner, Inner), BMS_SCHEMA_FIELD(St, hysteresis_v),
                         BMS_SCHEMA_FIELD(St, current_a)};
  static_assert(covers(f, sizeof(St), alignof(St)), "EffectsModel::State changed: update its schema table");
  return fnv_number(hash("EffectsModel.State", f, sizeof(St)), Effects);
}

// The film paths' states: each path's own parts (film_path.hpp). The path is in the core's
// schema, so an image of one path never restores into a core of the other.
template <class S, int Nc, int D>
constexpr std::uint32_t state_schema(Type<RcsiFilmPath<S, Nc, D>> /*tag*/) {
  using P = RcsiFilmPath<S, Nc, D>;
  using St = typename P::State;
  constexpr Field f[] = {BMS_SCHEMA_NESTED(St, estimator, typename P::Estimator),
                         BMS_SCHEMA_NESTED(St, bias, BiasCalibration<S>), BMS_SCHEMA_NESTED(St, film, FilmLevel<S>)};
  static_assert(covers(f, sizeof(St), alignof(St)), "RcsiFilmPath::State changed: update its schema table");
  return hash("RcsiFilmPath.State", f, sizeof(St));
}

template <class S>
constexpr std::uint32_t state_schema(Type<IdentifierFilmPath<S>> /*tag*/) {
  using St = typename IdentifierFilmPath<S>::State;
  constexpr Field f[] = {BMS_SCHEMA_NESTED(St, identifier, FilmGrowthIdentifier<S>)};
  static_assert(covers(f, sizeof(St), alignof(St)), "IdentifierFilmPath::State changed: update its schema table");
  return hash("IdentifierFilmPath.State", f, sizeof(St));
}

template <class S>
constexpr std::uint32_t state_schema(Type<AreaScale<S>> /*tag*/) {
  using St = typename AreaScale<S>::State;
  constexpr Field f[] = {BMS_SCHEMA_FIELD(St, scale),
                         BMS_SCHEMA_FIELD(St, weight),
                         BMS_SCHEMA_FIELD(St, counted_mol),
                         BMS_SCHEMA_FIELD(St, counted_carry_mol),
                         BMS_SCHEMA_FIELD(St, pinned_anode_mol),
                         BMS_SCHEMA_FIELD(St, pinned_loss_mol),
                         BMS_SCHEMA_FIELD(St, span_inventory_mol),
                         BMS_SCHEMA_FIELD(St, flags)};
  static_assert(covers(f, sizeof(St), alignof(St)), "AreaScale::State changed: update its schema table");
  return hash("AreaScale.State", f, sizeof(St));
}

template <class S, class M, int Nc, int D, class P>
constexpr std::uint32_t state_schema(Type<BmsCore<S, M, Nc, D, P>> /*tag*/) {
  using C = BmsCore<S, M, Nc, D, P>;
  using St = typename C::State;
  constexpr Field f[] = {BMS_SCHEMA_NESTED(St, film_path, P),
                         BMS_SCHEMA_FIELD(St, layout_tag),
                         BMS_SCHEMA_FIELD(St, ticks),
                         BMS_SCHEMA_FIELD(St, stale_ticks),
                         BMS_SCHEMA_FIELD(St, flags),
                         BMS_SCHEMA_FIELD(St, last_current_a),
                         BMS_SCHEMA_FIELD(St, last_j_side_a_m3),
                         BMS_SCHEMA_NESTED(St, learning, LearningGate<S>),
                         BMS_SCHEMA_NESTED(St, resync, StateResync<S>),
                         BMS_SCHEMA_NESTED(St, offset, CurrentOffset<S>),
                         BMS_SCHEMA_NESTED(St, voltage_offset, VoltageOffset<S>),
                         BMS_SCHEMA_NESTED(St, area, AreaScale<S>),
                         BMS_SCHEMA_NESTED(St, detector, typename C::Detector),
                         BMS_SCHEMA_NESTED(St, model, M)};
  static_assert(covers(f, sizeof(St), alignof(St)), "BmsCore::State changed: update its schema table");
  return hash("BmsCore.State", f, sizeof(St));
}

/// The schema hash of T's saved State (T: the owner class, e.g. a BmsCore instantiation).
template <class T>
constexpr std::uint32_t state_schema_hash() {
  return state_schema(Type<T>{});
}

}  // namespace bms::fw::schema
