#pragma once
// Baseline 1: an extended Kalman filter on the firmware's reduced model with the film
// resistance appended to the state as a random walk.
//
// State: the model's 25 concentrations (anode shells, cathode shells, electrolyte cells) and
// R_film. The model's lithium-loss and charge counters are carried but not estimated: nothing
// in the voltage depends on them. All filter algebra is in scaled coordinates (each
// concentration over its maximum or initial value, R_film over the paper cell's initial film),
// so P spans a few decades instead of twenty.
//
// The model's voltage at tick k follows from the state at the start of the tick and the tick's
// input (backward Euler), so tick k
//   1. linearises one step: F = d x(k) / d x(k-1) (R_film column included), H = dV(k) / d x(k-1),
//      b = d x(k) / d u(k), by forward differences on copies of the model;
//   2. in an update tick: innovation y(k) - V(k), variance S = H P H' + sigma_v^2 +
//      sigma_i^2 (dV/dI)^2 (the current noise mapped through the tick's own current), gain
//      K = P H' / S, correction of x(k-1) and R_film, Joseph form
//      P = (I - K H) P (I - K H)' + K r K'; then the step is repeated from the corrected state;
//   3. propagates P = F P F' + b b' sigma_u^2 + Q dt, with sigma_u the noise of the input
//      that drives the model this tick (current, or voltage in CV), Q = diag(q_c^2, .., q_r^2).
// The cross-correlation of the input noise between the step and the measurement is ignored.
//
// Updates happen only in constant-current charge by default, like RCSI, which is only active
// there: the comparison then uses the same information. `update_all_cc` also learns in CC
// discharge (dV/dR_film = -j_n is nonzero there too) to show what that adds.
#include <Eigen/Dense>

#include "baselines/noise_levels.hpp"
#include "baselines/reduced_track.hpp"

namespace bms::baselines {

struct EkfConfig {
  // Random walk of R_film [ohm m2 / sqrt(s)]. The paper cell's film grows by about 9e-9 ohm m2/s
  // in CC charge; with 1e-7 the filter's lag on that drift is about 100 s (sigma_v = 0.02 mV) to
  // 1000 s (0.2 mV), i.e. 0.03 % to 0.3 % of R_film.
  double q_r_ohm_m2_per_sqrt_s = 1e-7;
  // Model-error random walk on each concentration [fraction of its scale per sqrt(s)]. 0 by
  // default: the state is then uncertain only through the input noise and P(0).
  double q_conc_rel_per_sqrt_s = 0.0;
  double p0_r_rel = 0.1;      // initial std of R_film relative to the paper cell's initial film
  double p0_conc_rel = 1e-3;  // initial std of a uniform shift of each region's concentration
  bool update_all_cc = false;
  // Innovation gate [standard deviations of the innovation]; 0 = off. Needed on this model:
  // in the first ticks of each CC charge after the deep discharge the reduced model is off by
  // up to 17 mV (docs/results/firmware-model.md), hundreds of sigma, and an ungated filter
  // answers with a film resistance of the wrong sign and a state it never recovers from.
  double gate_sigmas = 5.0;
  // Model error [V std] added to the measurement variance: the reduced model's voltage in CC
  // charge is off by 0.29 mV RMS when given the true film (docs/results/firmware-model.md),
  // ten times the paper's smallest sensor noise. A filter told only about the sensor trusts
  // each sample too much and, with the gate, ends up rejecting every sample. 0 = sensor
  // noise only (right when the data come from the reduced model itself).
  double model_error_v = 0.3e-3;
};

struct EkfTick {
  double r_film_ohm_m2, r_sigma_ohm_m2, voltage_v, innovation_v;
  bool updated;
  bool gated;  // an update tick whose innovation the gate rejected
};

class AugmentedEkf {
 public:
  static constexpr int kConc = Cell::kNrN + Cell::kNrP + Cell::kNx;
  static constexpr int kN = kConc + 1;
  static constexpr int kR = kConc;  // index of R_film
  using Vec = Eigen::Matrix<double, kN, 1>;
  using Mat = Eigen::Matrix<double, kN, kN>;

  AugmentedEkf(const EkfConfig& config, const NoiseLevels& noise, const Cell& initial, double r_film_init_ohm_m2);

  // One tick; learns from the measured voltage when `update` (current-driven ticks only).
  EkfTick tick(const Track& t, std::size_t i, bool update);

  double r_film_ohm_m2() const { return r_film_; }
  double r_sigma_ohm_m2() const;
  const Mat& covariance_scaled() const { return p_; }
  const Cell& model() const { return cell_; }

 private:
  struct Linearisation;
  Linearisation linearise(const Track& t, std::size_t i, double u, bool by_voltage) const;
  bool correct(const Track& t, std::size_t i, double u, const Linearisation& lin, EkfTick& out);
  Vec pack(const Cell::State& s) const;            // scaled concentrations, R_film slot = 0
  void unpack(const Vec& x, Cell::State& s) const;  // concentrations only

  EkfConfig config_;
  NoiseLevels noise_;
  Cell cell_;
  double r_film_;
  Vec scale_;
  Mat p_;
};

// Runs the filter over the whole track.
struct EkfRun {
  std::vector<double> r_est, r_sigma, model_voltage_v;
  std::size_t updates = 0, gated = 0;
};
EkfRun run_ekf(const Track& t, const NoiseLevels& noise, const EkfConfig& config, const Cell& initial,
               double r_film_init_ohm_m2);

}  // namespace bms::baselines
