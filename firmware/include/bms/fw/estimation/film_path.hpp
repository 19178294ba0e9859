#pragma once
// The film path: what BmsCore learns the film resistance with, chosen as a type (static
// polymorphism, no virtual, no branch on a variant flag in the tick). Two paths:
//   RcsiFilmPath<Scalar, Nc, D>  (rcsi_film_path.hpp)       the paper's RCSI, with the bias
//                                calibration and the held / averaged / propagated film level;
//   IdentifierFilmPath<Scalar>   (identifier_film_path.hpp) the film, its growth gain and the
//                                lithium inventory identified in output-error form.
// A profile names its path (make_config.hpp: film_path_of); the board images fix it at build
// time, the host picks the core at start (with_core_for).
//
// Every path has the same small interface, called by BmsCore's tick steps:
//   kKind, Config, State (trivially copyable, for the NVM image)
//   Path(const Config&, Scalar dt_s)
//   initial_j_side_a_m3()                      the side current before the first tick
//   step 4: charge_ended(), ready_to_learn(), should_collect_reference(cc, warm, resyncs),
//           window_opens(last_j_side)
//   step 5: film_in_use(open)
//   step 6: learns_from_probes(gate, open, voltage_driven), probe(model, current, u, dt, inventory)
//   step 7: inventory_deviation(), relinearise_inventory(), relinearise(), forget() (the
//           current sensor's offset in use changed: what was learned on the old one is dropped)
//   step 8: collect_reference(z)
//   step 9: learn(tick, model, gate, resync)   (the film's propagation over the tick included)
//   catch-up and model failure: propagate(j_side, dt), model_failed(open, last_j_side)
//   outputs: r_film_ohm_m2(), film_sd_ohm_m2(), innovation_test_ratio(), write_outputs(out, sd), status()
//   NVM: save(), restore(state), inventory_limit() (the re-synchronisation's restore range)
// Header-only C++17: no heap, no exceptions, no RTTI.
#include <cstdint>

#include "bms/fw/estimation/fw_status.hpp"
#include "bms/fw/model/reduced_cell.hpp"

namespace bms::fw {

enum class FilmPathKind : std::uint8_t { rcsi, identifier };

inline const char* film_path_name(FilmPathKind k) { return k == FilmPathKind::rcsi ? "rcsi" : "identifier"; }

// What step 9 hands the path: this tick's model step and residual.
template <typename Scalar>
struct FilmTick {
  ModelTickResult<Scalar> r{};     // the model's step
  Scalar current_a{};              // the measured current, in the model's units (AreaScale: / a)
  Scalar u_ohm_m2{};               // the film the model ran with (step 5)
  Scalar z_v{};                    // y_hat - y
  Scalar v_probe_v{};              // the model's voltage at the probed inventory (probes only)
  Scalar dt_s{};
  Scalar nominal_inventory_mol{};
  bool open{};                     // the learning window is open
  bool probed{};                   // learns_from_probes() was true: the probes ran
  Scalar area_scale = Scalar(1);  // the identified electrode-capacity scale (AreaScale): the capacity's factor
  // The model's inventory plus its loss at the span that measured the scale (NaN: none yet).
  Scalar area_inventory_mol = Scalar(0) / Scalar(0);
};

// What step 9 gives back.
template <typename Scalar>
struct FilmLearned {
  StatusWord status;
  bool active;                      // the film's parameters were updated
  Scalar inventory_sensitivity_v;   // S = dV/dnu (identifier), 0 otherwise
};

}  // namespace bms::fw
