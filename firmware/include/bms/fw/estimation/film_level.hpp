#pragma once
// The film resistance RCSI's path reports and holds (the paper and nominal-growth profiles; the
// `best` profile reports the FilmGrowthIdentifier's instead): the level
// RCSI's data set, optionally averaged over the charge's learning window, plus the growth the
// model's own side current predicts since that level was set.
//   average: the mean of u_hat over the window instead of its last value. The film changes by
//            about 1 % per charge while the RCSI loop (M1 ~ 1: two integrators) oscillates by a few %;
//   growth:  dR_film = -k j_side dt, k the *nominal* cell's Ramadass law
//            (ReducedCell::nominal_film_growth_ohm_m2_per_a_m3_s()), assumed, not learned. The film
//            grows about 0.9 % during each CC charge, and a held estimate lags it by about half of that.
// Header-only C++17: no heap, no exceptions, no RTTI.
#include <cmath>
#include <cstdint>

namespace bms::fw {

template <typename Scalar>
class FilmLevel {
 public:
  struct Config {
    bool average = false;
    Scalar growth_ohm_m2_per_a_m3_s = Scalar(0);  // 0: held (the paper)
  };

  // Trivially copyable, for the NVM image.
  struct State {
    Scalar r_held_ohm_m2;
    Scalar growth_ohm_m2;
    Scalar avg_sum_ohm_m2;
    std::uint32_t avg_samples;
    std::uint32_t reserved;
  };

  FilmLevel(const Config& config, Scalar r_film_init_ohm_m2) : c_(config), r_held_(r_film_init_ohm_m2) {}

  // A learning window opens: the predicted growth is folded into the held value, so its sum stays
  // a small number (float keeps the per-tick increments, about 1e-8 of R_film). Returns the film
  // held so far, RCSI's history restarts from it.
  Scalar begin_charge() {
    r_held_ += growth_;
    growth_ = Scalar(0);
    avg_sum_ = Scalar(0);
    avg_samples_ = 0u;
    return r_held_;
  }
  void record(Scalar level_ohm_m2) {
    r_held_ = level_ohm_m2;
    if (c_.average) {
      avg_sum_ += level_ohm_m2;
      ++avg_samples_;
      r_held_ = avg_sum_ / static_cast<Scalar>(avg_samples_);
    }
  }
  void add_growth(Scalar j_side_a_m3, Scalar dt_s) { growth_ -= c_.growth_ohm_m2_per_a_m3_s * j_side_a_m3 * dt_s; }

  Scalar growth_ohm_m2() const { return growth_; }
  Scalar value_ohm_m2() const { return r_held_ + growth_; }

  State save() const { return State{r_held_, growth_, avg_sum_, avg_samples_, 0u}; }
  // Within the admissible film range [r_lo, r_hi] widened by its span (the average's sum within its
  // sample count times that): finite alone let 1e308 through, and every output became infinite.
  bool restore(const State& s, Scalar r_lo, Scalar r_hi) {
    auto within = [](Scalar v, Scalar lo, Scalar hi) { return std::isfinite(v) && v >= lo && v <= hi; };
    const Scalar r_span = r_hi - r_lo;
    const auto n = static_cast<Scalar>(s.avg_samples);
    const bool ok = within(s.avg_sum_ohm_m2, r_lo * n - r_span, r_hi * n + r_span) &&
                    within(s.r_held_ohm_m2, r_lo - r_span, r_hi + r_span) && within(s.growth_ohm_m2, -r_span, r_span) &&
                    s.reserved == 0u;
    if (!ok) return false;
    r_held_ = s.r_held_ohm_m2;
    growth_ = s.growth_ohm_m2;
    avg_sum_ = s.avg_sum_ohm_m2;
    avg_samples_ = s.avg_samples;
    return true;
  }

 private:
  Config c_;
  Scalar r_held_;
  Scalar growth_ = Scalar(0);
  Scalar avg_sum_ = Scalar(0);
  std::uint32_t avg_samples_ = 0u;
};

}  // namespace bms::fw
