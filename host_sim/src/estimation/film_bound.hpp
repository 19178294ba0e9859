#pragma once
// Cramer-Rao bound of the best profile's joint unknowns, theta = [R0, g, nu] (initial film,
// growth gain, relative lithium inventory), for the same data, noise and information as the
// estimator: the linearised measurement z(k) = H(k) (R0 + g G(k)) + S(k) nu + e(k) over the
// ticks in which it learned, e white with the effective voltage noise. The bound on the film
// at a tick is sqrt(a^T J^-1 a), a = [1, G(k), 0], with J built from the data up to that tick.
// The bound on the growth growth_err_pct scores (the film's change from growth_span's ref to its
// last row, g (G_last - G_ref)) takes a = [0, G_last - G_ref, 0] and J from all the data: an
// unbiased estimate of that change from this record, whatever it does, scatters at least so much.
#include <cmath>
#include <vector>

#include "cell/cell_parameters.hpp"
#include "estimation/estimate_run.hpp"

namespace bms {

struct CycleBound {
  int cycle;
  double film_sd_pct;       // at the cycle's last CC-charge tick, relative to the true film
  double inventory_sd_pct;  // of nu, with the data up to then
};

struct FilmBound {
  std::vector<CycleBound> cycles;
  double r0_sd_ohm_m2 = 0.0, gain_sd = 0.0, inventory_sd_pct = 0.0;  // with all the data
  // The growth over growth_span: its bound [ohm m2], and that relative to the true growth there
  // (%; NaN without a valid span or a truth that grew): growth_err_pct's own 1-sigma floor.
  double growth_sd_ohm_m2 = std::nan(""), growth_sd_pct = std::nan("");
  bool valid = false;  // false: no learning tick, or J singular
};

// rows: an estimate run of the best profile (H, S, G recorded per tick). sigma_v: standard
// deviation of the voltage noise the estimator sees [V], current noise folded in by the caller.
FilmBound film_cramer_rao(const std::vector<EstimateRow>& rows, double sigma_v);

// The voltage noise the estimator sees: sqrt(sigma_v^2 + (R sigma_i)^2), R = dV/dI of the
// cell's nominal reduced model (the firmware's, as the estimator runs it) at the start of a CC
// charge at `current_a` (one tick), from the cell's 0 % state of charge.
double effective_voltage_noise_v(double sigma_v, double sigma_i, double current_a, const CellParameters& cell);

}  // namespace bms
