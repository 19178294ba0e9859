#pragma once
// RCSI of the SEI film in output-error form: the estimator of the `best` profile
// (docs/results/blind.md). It knows the nominal cell only; what the cell's film does is learned.
//
// Subsystem model (structure assumed, constants identified):
//   R_film(k) = R0 + g G(k),   G(k) = -k_nom * sum_{i<k} j_s(i) dt
// which is the paper's first-order subsystem R(k) = M1 R(k-1) + N1 j_s(k-1) with M1 = 1 (an
// integrator: the film only grows) written with its state: R0 is the unknown initial film and g
// the unknown gain of the growth law relative to the nominal cell's Ramadass constant k_nom
// (N1 = -g k_nom dt). In the ARX (equation-error) form the per-tick growth (1e-8 ohm m2) is
// four orders below the noise of one u*; in this output-error form every tick of every charge
// informs R0 and g.
//
// Beside the film, the cell's lithium inventory is a main-system parameter the data inform: a
// relative deviation nu from the nominal inventory moves the model's voltage by S = dV/dnu
// (MainModel::inventory_probe_voltage), with a shape over a charge that differs from the film's
// nearly constant H. It is the third parameter of the same regression.
//
// Retrospective step (D = 0, eta = 0): the model answers u_hat(k) within the tick and the film
// drop is linear in R_film, so u*(k) = u_hat(k) - (z(k) - b(k)) / H(k) is the film the data
// imply; b is the reduced model's design-time voltage bias (computed once from the nominal cell,
// see Config::model_bias_ohm). With z = H (u_hat - R) + S (nu_model - nu) + b + noise:
//   u*(k) + (S/H) nu_model - g^ (G(k) - G_c)  =  theta^T [1, G_c, S(k)/H(k)],   theta = [R0, g, nu]
// which RLS (lambda = 1, never reset: the information of every charge is kept) fits. G_c is G at
// the start of the charge's learning: g is learned from how the level moves between charges,
// not from the trend within one, where the model's own bias drifts by about as much as the film
// grows (0.02 against 0.03-0.05 mV); the growth within the charge is the current estimate's.
//
// When it learns (named as in PX4 EKF2's aid sources): start when the tick is in CC charge past
// the warm-up and the model gave a valid H > 0; continue while so; stop (hold theta) otherwise.
#include <cstddef>
#include <cmath>
#include <cstdint>
#include <limits>
#include <type_traits>

#include <Eigen/Core>

#include "bms/fw/estimation/fw_status.hpp"
#include "bms/fw/estimation/rls.hpp"

namespace bms::fw {

template <typename Scalar = double>
class FilmGrowthIdentifier {
  static_assert(std::is_floating_point<Scalar>::value, "Scalar must be a floating-point type");

 public:
  static constexpr int kParams = 3;
  // The regression runs in double whatever Scalar is. Within one charge G_c is constant, so the
  // regressors 1 and G_c are collinear there and R0 and g are told apart only across charges: P
  // is nearly singular (R0 and g correlated to within 1e-4), and float's covariance update
  // loses its small direction (measured on a 3-cycle blind truth: the gain learned in float
  // 0.57 % from double's, 0.05 % with this part in double; docs/results/target.md). On a
  // Cortex-M4F this is software double: one update per learning tick.
  using Real = double;
  using RlsType = Rls<Real, kParams>;
  using RlsState = typename RlsType::State;
  using Vector = Eigen::Matrix<Scalar, kParams, 1>;

  struct Config {
    Scalar r_film_nominal_ohm_m2 = Scalar(0);  // theta(0): the nominal cell's initial film
    // Nominal Ramadass constant k_nom [ohm m2 per (A/m3) s]: G's unit is ohm m2 at g = 1.
    Scalar growth_nominal_ohm_m2_per_a_m3_s = Scalar(0);
    // Prior standard deviations of R0 [ohm m2], g [-] and nu [-], and the assumed standard
    // deviation of one u* [ohm m2]; P(0) = diag(prior / sigma_u)^2. Weak priors: the data
    // decide after one charge.
    Scalar prior_r0_ohm_m2 = Scalar(1e-3);
    Scalar prior_gain = Scalar(1);
    Scalar prior_inventory = Scalar(0.02);
    Scalar sigma_u_ohm_m2 = Scalar(1e-4);
    Scalar r_film_min_ohm_m2 = Scalar(0);
    Scalar r_film_max_ohm_m2 = Scalar(1);
    Scalar inventory_limit = Scalar(0.05);  // |nu| the model is ever moved by
    bool learn_inventory = true;            // ablation: false keeps nu at 0 (the nominal inventory)
    // What the data cannot separate from the film level and the inventory, as a stated 1-sigma
    // bound beside the regression's own covariance: the reduced model's structural error, which
    // in CC charge is collinear with the film (docs/results/envelope.md). Calibrated on the blind
    // study's set 1 (nominal transport and kinetics; median film error 0.67 %, 90th percentile
    // 1.19 %: 0.6 % puts the 90th percentile at 2 sd) and set 2 for the inventory (median 0.04 %,
    // 90th percentile 0.12 %). A cell whose kinetics or transport are not the nominal ones can be
    // further off than this: the level is then not separable from the film (the physics).
    Scalar film_model_sd_rel = Scalar(0.006);
    Scalar inventory_model_sd = Scalar(5e-4);
    // The cell's stated tolerance of its initial film (relative 1-sigma of the nominal one; a lot
    // tolerance, never learned), the prior's initial-film sd wherever the prior is reported: held
    // before a fit settles, or combined with a fit under a stated spread (prior_film_sd_ohm_m2,
    // prior_level_film_sd_ohm_m2). 0: the regression's weak prior prior_r0_ohm_m2, which says the
    // data decide and is no statement about the cell. The regression itself keeps prior_r0_ohm_m2:
    // the fit stays the data's, so the prior is counted once.
    Scalar stated_film_initial_sd_rel = Scalar(0);
  };

  struct State {
    typename RlsType::State rls;
    Scalar growth_ohm_m2;            // G(k)
    Scalar growth_at_charge_ohm_m2;  // G_c
    Scalar growth_carry_ohm_m2;      // compensation of G's sum (Kahan): G = growth + carry
  };
  static_assert(std::is_trivially_copyable<State>::value, "State must be trivially copyable");

  explicit FilmGrowthIdentifier(const Config& c) : config_(c), rls_(make_rls_config(c)) { refresh(); }

  // The film resistance in use at this tick: theta_R0 + theta_g G, within the admissible range.
  Scalar film_ohm_m2() const { return admissible_film_ohm_m2(theta_(0) + theta_(1) * growth_); }
  // Relative inventory deviation the model should be placed at (clipped to the limit).
  Scalar inventory_deviation() const {
    const Scalar nu = theta_(2);
    if (!std::isfinite(nu)) return Scalar(0);
    const Scalar lim = config_.inventory_limit;
    return nu < -lim ? -lim : (nu > lim ? lim : nu);
  }
  // 1-sigma of the film in use: the regression's, sigma_u^2 [1 G 0] P [1 G 0]^T, and the stated
  // model bound film_model_sd_rel x film, added in quadrature.
  Scalar film_sd_ohm_m2() const {
    const auto& p = rls_.p();
    const Real g = static_cast<Real>(growth_), su = static_cast<Real>(config_.sigma_u_ohm_m2);
    const Real v = (p(0, 0) + Real(2) * g * p(0, 1) + g * g * p(1, 1)) * su * su;
    const Real m = static_cast<Real>(config_.film_model_sd_rel * film_ohm_m2());
    const Real sd = std::sqrt((v > Real(0) ? v : Real(0)) + m * m);
    return static_cast<Scalar>(sd);
  }
  // The prior's film and its 1-sigma at this tick: what an identifier that never learned reports
  // (theta(0) = the nominal film and gain 1, P(0) = the stated priors, with the same G and the
  // same model bound): the nominal cell's film grown by the nominal law.
  Scalar prior_film_ohm_m2() const { return admissible_film_ohm_m2(config_.r_film_nominal_ohm_m2 + growth_); }
  Scalar prior_film_sd_ohm_m2() const {
    const Real g = static_cast<Real>(growth_), pr = prior_initial_film_sd_ohm_m2(),
               pg = static_cast<Real>(config_.prior_gain);
    const Real m = static_cast<Real>(config_.film_model_sd_rel * prior_film_ohm_m2());
    return static_cast<Scalar>(std::sqrt(pr * pr + g * g * pg * pg + m * m));
  }
  // The prior's level with this fit's growth: the nominal initial film plus the fitted gain's G,
  // and its 1-sigma (the prior's level, the fitted gain's regression sd over G, the model bound).
  // What a stated cell-to-cell spread leaves the prior to inform: the spread offsets the film's
  // level for the cell's whole life (collinear with theta_R0), not its growth.
  Scalar prior_level_film_ohm_m2() const {
    return admissible_film_ohm_m2(config_.r_film_nominal_ohm_m2 + theta_(1) * growth_);
  }
  Scalar prior_level_film_sd_ohm_m2() const {
    const Real g = static_cast<Real>(growth_), pr = prior_initial_film_sd_ohm_m2(),
               su = static_cast<Real>(config_.sigma_u_ohm_m2), vg = rls_.p()(1, 1) * su * su;
    const Real m = static_cast<Real>(config_.film_model_sd_rel * prior_level_film_ohm_m2());
    return static_cast<Scalar>(std::sqrt(pr * pr + g * g * (vg > Real(0) ? vg : Real(0)) + m * m));
  }
  // Whether the film's regression variance (what the data since the last relinearise() left
  // open) is within the stated model bound: the estimate no longer moves by more than the
  // model's own error as the next samples come in.
  bool settled() const {
    const auto& p = rls_.p();
    const Real g = static_cast<Real>(growth_), su = static_cast<Real>(config_.sigma_u_ohm_m2);
    const Real v = (p(0, 0) + Real(2) * g * p(0, 1) + g * g * p(1, 1)) * su * su;
    const Real m = static_cast<Real>(config_.film_model_sd_rel * film_ohm_m2());
    return v <= m * m;
  }
  // 1-sigma of the relative inventory deviation nu, in the same way.
  Scalar inventory_sd() const {
    const Real su = static_cast<Real>(config_.sigma_u_ohm_m2), m = static_cast<Real>(config_.inventory_model_sd);
    const Real v = rls_.p()(2, 2) * su * su;
    return static_cast<Scalar>(std::sqrt((v > Real(0) ? v : Real(0)) + m * m));
  }
  Scalar gain() const { return theta_(1); }
  Scalar initial_film_ohm_m2() const { return theta_(0); }
  Scalar growth_ohm_m2() const { return growth_; }
  const Vector& theta() const { return theta_; }
  const typename RlsType::Matrix& p() const { return rls_.p(); }

  // The first learning tick of a CC charge (see the header: G_c).
  void begin_charge() { growth_at_charge_ = growth_; }

  // Every model tick, in every mode: the film grows whether or not it is observed.
  // G is a sum over the cell's life of per-tick steps of about 2e-9 ohm m2: in float, once G
  // passes 0.03 ohm m2 a plain sum would drop every step, so the lost low part is carried.
  void propagate(Scalar j_side_a_m3, Scalar dt_s) {
    if (!std::isfinite(j_side_a_m3)) return;
    const Scalar y = -config_.growth_nominal_ohm_m2_per_a_m3_s * j_side_a_m3 * dt_s + growth_carry_;
    const Scalar sum = growth_ + y;
    growth_carry_ = y - (sum - growth_);
    growth_ = sum;
  }

  // The regression's a-priori innovation of one learning tick in volts, H (y - phi^T theta): what
  // the fitted film, gain and inventory leave of this tick's residual (the arguments as learn()'s).
  // Unlike the residual z, it does not carry the model's distance from the fitted inventory (the
  // model moves to it only at the next re-synchronisation). NaN where learn() would reject.
  Scalar innovation_v(Scalar u_hat_ohm_m2, Scalar z_v, Scalar h_v_per_ohm_m2, Scalar s_v, Scalar nu_model,
                      Scalar bias_v) const {
    if (!std::isfinite(z_v) || !std::isfinite(h_v_per_ohm_m2) || !(h_v_per_ohm_m2 > Scalar(0)))
      return std::numeric_limits<Scalar>::quiet_NaN();
    const Real y = regressand(u_hat_ohm_m2, z_v, h_v_per_ohm_m2, s_v, nu_model, bias_v);
    const Real e = y - regressor(h_v_per_ohm_m2, s_v).dot(rls_.theta());
    return static_cast<Scalar>(static_cast<Real>(h_v_per_ohm_m2) * e);
  }

  // One learning tick. u_hat: the film the model used; z = y_hat - y [V]; H = dV/dR_film [V per
  // ohm m2]; S = dV/dnu [V] (0 or non-finite: no inventory information); nu_model: the inventory
  // deviation the model was placed at; bias_v: the model's design-time bias at this current.
  StatusWord learn(Scalar u_hat_ohm_m2, Scalar z_v, Scalar h_v_per_ohm_m2, Scalar s_v, Scalar nu_model,
                   Scalar bias_v) {
    if (!std::isfinite(z_v) || !std::isfinite(h_v_per_ohm_m2) || !(h_v_per_ohm_m2 > Scalar(0)))
      return bit(FwStatus::kRejectedNonFinite);
    const StatusWord st = rls_.update(regressor(h_v_per_ohm_m2, s_v),
                                      regressand(u_hat_ohm_m2, z_v, h_v_per_ohm_m2, s_v, nu_model, bias_v));
    refresh();
    return st;
  }

 private:
  // phi = [1, G_c, S/H] and y = u* + (S/H) nu_model - g^ (G - G_c) of one tick (the header).
  Scalar s_over_h(Scalar h_v_per_ohm_m2, Scalar s_v) const {
    return config_.learn_inventory && std::isfinite(s_v) ? s_v / h_v_per_ohm_m2 : Scalar(0);
  }
  typename RlsType::Vector regressor(Scalar h_v_per_ohm_m2, Scalar s_v) const {
    typename RlsType::Vector phi;
    phi << Real(1), static_cast<Real>(growth_at_charge_), static_cast<Real>(s_over_h(h_v_per_ohm_m2, s_v));
    return phi;
  }
  Real regressand(Scalar u_hat_ohm_m2, Scalar z_v, Scalar h_v_per_ohm_m2, Scalar s_v, Scalar nu_model,
                  Scalar bias_v) const {
    const Scalar u_star = u_hat_ohm_m2 - (z_v - bias_v) / h_v_per_ohm_m2;
    const Real within_charge = rls_.theta()(1) * static_cast<Real>(growth_ - growth_at_charge_);
    return static_cast<Real>(u_star) + static_cast<Real>(s_over_h(h_v_per_ohm_m2, s_v) * nu_model) - within_charge;
  }

 public:
  // The model was moved to an inventory far from where the data so far were linearised (S is
  // a tangent: 1 % of inventory is 3-12 mV over a charge, and the tangent's error on it is read
  // as film and as inventory): forget what was learned, keep the values as the prior mean.
  void relinearise() {
    typename RlsType::State st = rls_.save();
    const auto p0 = make_rls_config(config_).p0_diag;
    for (Real& p : st.p) p = Real(0);
    for (int i = 0; i < kParams; ++i) st.p[static_cast<std::ptrdiff_t>(i) * (kParams + 1)] = p0(i);
    rls_.restore(st);
    refresh();
  }

  // What was learned came from data the model cannot explain any more (the current sensor's
  // offset was removed from the samples since: BmsCore): forget it and its values, and start
  // again from the prior (mean and covariance) as at power-up. G, the nominal law's integral, is
  // the cell's history, not learned: it is kept.
  void restart_from_prior() {
    rls_ = RlsType(make_rls_config(config_));
    refresh();
  }

  // The fit alone (theta and P), without G: the cell's history goes on whatever was learned.
  typename RlsType::State fit() const { return rls_.save(); }
  // Back to a fit saved by fit() (a charge's stop condition: IdentifierFilmPath); an invalid one
  // changes nothing.
  void restore_fit(const typename RlsType::State& s) {
    if (rls_.restore(s)) refresh();
  }

  State save() const { return State{rls_.save(), growth_, growth_at_charge_, growth_carry_}; }
  bool restore(const State& s) {
    RlsType candidate = rls_;
    // G is a film resistance: beyond the admissible film range it cannot be (a finite 1e308
    // would make every later estimate infinite); its compensation carry is smaller still.
    const Scalar g_max = config_.r_film_max_ohm_m2 - config_.r_film_min_ohm_m2;
    auto within = [g_max](Scalar g) { return std::isfinite(g) && g >= -g_max && g <= g_max; };
    if (!within(s.growth_ohm_m2) || !within(s.growth_at_charge_ohm_m2) || !within(s.growth_carry_ohm_m2) ||
        !candidate.restore(s.rls))
      return false;
    rls_ = candidate;
    growth_ = s.growth_ohm_m2;
    growth_at_charge_ = s.growth_at_charge_ohm_m2;
    growth_carry_ = s.growth_carry_ohm_m2;
    refresh();
    return true;
  }

 private:
  // A film within the admissible range; the nominal one where it is not finite.
  Scalar admissible_film_ohm_m2(Scalar r) const {
    if (!std::isfinite(r)) return config_.r_film_nominal_ohm_m2;
    return r < config_.r_film_min_ohm_m2 ? config_.r_film_min_ohm_m2
                                         : (r > config_.r_film_max_ohm_m2 ? config_.r_film_max_ohm_m2 : r);
  }
  // The prior's initial-film 1-sigma wherever the prior is reported: the stated tolerance, else
  // the regression's weak prior (Config::stated_film_initial_sd_rel).
  Real prior_initial_film_sd_ohm_m2() const {
    const Scalar stated = config_.stated_film_initial_sd_rel * config_.r_film_nominal_ohm_m2;
    return static_cast<Real>(stated > Scalar(0) ? stated : config_.prior_r0_ohm_m2);
  }
  static typename RlsType::Config make_rls_config(const Config& c) {
    typename RlsType::Config rc;
    rc.lambda = Real(1);
    const Real su = static_cast<Real>(c.sigma_u_ohm_m2);
    const Real pr = static_cast<Real>(c.prior_r0_ohm_m2), pg = static_cast<Real>(c.prior_gain),
               pi = static_cast<Real>(c.prior_inventory);
    rc.p0_diag << (pr / su) * (pr / su), (pg / su) * (pg / su), (pi / su) * (pi / su);
    rc.theta0 << static_cast<Real>(c.r_film_nominal_ohm_m2), Real(1), Real(0);
    rc.p_trace_cap_factor = Real(1);
    return rc;
  }

  // theta in Scalar, refreshed at each change: every tick reads the film from it, and on a
  // Cortex-M4F a software-double read per tick (held ticks included) is not free.
  void refresh() { theta_ = rls_.theta().template cast<Scalar>(); }

  Config config_;
  RlsType rls_;
  Vector theta_ = Vector::Zero();
  Scalar growth_ = Scalar(0);
  Scalar growth_at_charge_ = Scalar(0);
  Scalar growth_carry_ = Scalar(0);
};

}  // namespace bms::fw
