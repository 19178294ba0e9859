// Drives an IdentifierFilmPath through learning ticks of a 1C charge whose innovation is exactly
// H (u - R_true): no noise, no inventory information. Shared by the tests of the path's sd terms.
#pragma once

#include "bms/fw/estimation/identifier_film_path.hpp"

namespace bms::fw::test {

inline constexpr double kPathChargeA = -2.5;  // 1C charge
inline constexpr double kPathDtS = 0.2;
inline constexpr double kPathH = 0.9;  // dV/dR_film [V per ohm m2] at a 1C charge tick, about

// A path over the given nominal film with a small nominal law and no temperature term: what the
// tests of the path's terms start from.
inline IdentifierFilmPath<double>::Config plain_path_config(double film_ohm_m2) {
  IdentifierFilmPath<double>::Config c;
  c.identifier.r_film_nominal_ohm_m2 = film_ohm_m2;
  c.identifier.growth_nominal_ohm_m2_per_a_m3_s = 1e-12;
  c.temperature_sd_k = 0.0;
  return c;
}

template <class Model>
void learn_ticks(IdentifierFilmPath<double>& path, const Model& model, int ticks, double true_ohm_m2) {
  LearningGate<double> gate(LearningGate<double>::Config{});
  const StateResync<double> resync(StateResync<double>::Config{});
  for (int k = 0; k < ticks; ++k) {
    const double u = path.film_in_use(true);
    FilmTick<double> t{};
    t.r = ModelTickResult<double>{3.6, kPathChargeA, -1.0, kPathH, 0, true, true};
    t.current_a = kPathChargeA;
    t.u_ohm_m2 = u;
    t.z_v = kPathH * (u - true_ohm_m2);
    t.v_probe_v = t.r.voltage_v;  // no inventory information
    t.dt_s = kPathDtS;
    t.nominal_inventory_mol = 0.0;
    t.open = true;
    t.probed = true;
    path.learn(t, model, gate, resync);
  }
}

}  // namespace bms::fw::test
