#pragma once
// Straight-line fit of measured voltage and current over a short window of ticks, evaluated
// at the window's last tick: the measurement a state re-synchronisation matches. One noisy
// sample moves the re-synchronised state by the noise (0.2 mV of voltage noise, or 5 mA of
// current noise through the cell's resistance, is several times the film's growth signal
// per charge); a line rather than a mean, because the CV current still decays by about 1 %
// per second when the window is taken, and a mean would lag it.
#include <cmath>
#include <cstdint>

namespace bms::fw {

template <typename Scalar>
class ResyncWindow {
 public:
  // Trivially copyable, for the NVM image.
  struct State {
    std::uint32_t samples;
    std::uint32_t length;  // 0: no window open
    Scalar v0_v;           // first sample: sums are of deviations from it (float keeps its digits)
    Scalar i0_a;
    Scalar sum_x;          // x = tick index in the window
    Scalar sum_xx;
    Scalar sum_v;
    Scalar sum_xv;
    Scalar sum_i;
    Scalar sum_xi;
  };

  struct Fit {
    Scalar voltage_v;
    Scalar current_a;
  };

  void open(std::uint32_t length_ticks) {
    s_ = State{};
    s_.length = length_ticks < 1u ? 1u : length_ticks;
  }
  void close() { s_ = State{}; }
  bool is_open() const { return s_.length != 0u; }
  bool full() const { return is_open() && s_.samples >= s_.length; }

  void add(Scalar voltage_v, Scalar current_a) {
    if (!is_open() || full()) return;
    if (s_.samples == 0u) {
      s_.v0_v = voltage_v;
      s_.i0_a = current_a;
    }
    const Scalar x = static_cast<Scalar>(s_.samples);
    const Scalar dv = voltage_v - s_.v0_v, di = current_a - s_.i0_a;
    s_.sum_x += x;
    s_.sum_xx += x * x;
    s_.sum_v += dv;
    s_.sum_xv += x * dv;
    s_.sum_i += di;
    s_.sum_xi += x * di;
    ++s_.samples;
  }

  // The fitted line at the last sample; with one sample, that sample.
  Fit fit() const {
    const Scalar n = static_cast<Scalar>(s_.samples);
    if (s_.samples < 2u) return Fit{s_.v0_v + s_.sum_v, s_.i0_a + s_.sum_i};
    const Scalar last = n - Scalar(1);
    const Scalar den = n * s_.sum_xx - s_.sum_x * s_.sum_x;
    auto at_last = [&](Scalar sum_y, Scalar sum_xy) {
      const Scalar slope = (n * sum_xy - s_.sum_x * sum_y) / den;
      return (sum_y - slope * s_.sum_x) / n + slope * last;
    };
    return Fit{s_.v0_v + at_last(s_.sum_v, s_.sum_xv), s_.i0_a + at_last(s_.sum_i, s_.sum_xi)};
  }

  const State& state() const { return s_; }
  bool restore(const State& s) {
    const bool finite = std::isfinite(s.v0_v) && std::isfinite(s.i0_a) && std::isfinite(s.sum_x) &&
                        std::isfinite(s.sum_xx) && std::isfinite(s.sum_v) && std::isfinite(s.sum_xv) &&
                        std::isfinite(s.sum_i) && std::isfinite(s.sum_xi);
    if (!finite || s.samples > s.length) return false;
    s_ = s;
    return true;
  }

 private:
  State s_{};
};

}  // namespace bms::fw
