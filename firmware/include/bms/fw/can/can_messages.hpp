// The BMS CAN protocol's messages as C++ values (SI units), the status and fault bits, and
// each message's binding to its row of the signal table (can_signal_table.hpp).
//
// A binding lists the struct's members in the order of the message's signals after the
// framing pair (Crc, Counter); the codec walks both together. It holds no bit positions or
// scales: those live only in the table.
//
// Header-only C++17: no heap, no exceptions, no RTTI; usable on a Cortex-M.
#pragma once

#include <cstdint>

#include "bms/fw/can/can_signal_table.hpp"
#include "bms/fw/estimation/operating_mode.hpp"

namespace bms::fw::can {


using fw::Mode;
using fw::mode_name;

constexpr Mode mode_from_raw(std::uint64_t raw) { return raw <= 4u ? static_cast<Mode>(raw) : Mode::unknown; }

/// BMS_Status.StatusBits
namespace status_bit {
inline constexpr std::uint8_t kRunning = 1u << 0;         ///< estimator initialised and stepping
inline constexpr std::uint8_t kRcsiActive = 1u << 1;      ///< RCSI updating (constant-current charging)
inline constexpr std::uint8_t kLockstep = 1u << 2;        ///< ticks driven by the host
inline constexpr std::uint8_t kMeasStale = 1u << 3;       ///< no valid measurement for more than 2 ticks
inline constexpr std::uint8_t kEstimateValid = 1u << 4;   ///< BMS_Estimate1.RFilm is meaningful
inline constexpr std::uint8_t kNvmRestored = 1u << 5;     ///< state restored from NVM at start-up
inline constexpr std::uint8_t kNvmRolledBack = 1u << 6;   ///< ... from the older slot (the newer was unreadable)
}  // namespace status_bit

/// BMS_Status.FaultBits
namespace fault_bit {
inline constexpr std::uint8_t kMeasStale = 1u << 0;      ///< measurement stale (latched until valid again)
inline constexpr std::uint8_t kRxDropped = 1u << 1;      ///< a frame was dropped since the previous Status
inline constexpr std::uint8_t kVoltageRange = 1u << 2;   ///< measured voltage outside the cell's limits
inline constexpr std::uint8_t kCurrentRange = 1u << 3;   ///< measured current outside the cell's limits
inline constexpr std::uint8_t kEstimator = 1u << 4;      ///< estimator produced a non-finite/out-of-range value
inline constexpr std::uint8_t kNvm = 1u << 5;            ///< NVM read/write failed or rolled back; clears at the next good commit
inline constexpr std::uint8_t kTickOverrun = 1u << 6;    ///< a tick over its time budget, or ticks skipped (real time)
inline constexpr std::uint8_t kInternal = 1u << 7;       ///< core call-order/config fault, a failed send, a refused reset, a clock mismatch
}  // namespace fault_bit

struct Control {
  bool reset_estimator = false;  ///< back to the power-on state (bms::app::BmsApplication)
  bool lockstep = false;         ///< 1: the host drives ticks; must match the firmware's mode (else fault bit 7)
  bool tick_trigger = false;     ///< 1: this frame triggers tick `tick` (lock-step)
  std::uint32_t tick = 0;
};

struct Measurement {
  std::uint16_t seq = 0;  ///< tick number mod 4096
  double voltage_v = 0.0;
  double current_a = 0.0;  ///< positive = discharge
};

struct Temperature {
  double temperature_k = 0.0;
};

struct Estimate1 {
  std::uint16_t seq = 0;
  double r_film_ohm_m2 = 0.0;
  Mode mode = Mode::unknown;
  bool rcsi_active = false;
  bool valid = false;
};

struct Estimate2 {
  std::uint16_t seq = 0;
  float theta0 = 0.0f;  ///< theta[0] (M1 for n_c = 1)
};

struct Estimate3 {
  std::uint16_t seq = 0;
  float theta1 = 0.0f;  ///< theta[1] (N1 for n_c = 1)
};

struct Health {
  std::uint16_t seq = 0;
  double li_loss_ah = 0.0;  ///< on the bus in mAh
  double z_v = 0.0;         ///< y_hat - y; on the bus in uV
};

struct Uncertainty {
  std::uint16_t seq = 0;
  double r_film_sd_ohm_m2 = 0.0;  ///< the estimator's 1-sigma of the film (NaN: none)
  double capacity_ah = 0.0;       ///< open-circuit capacity; on the bus in mAh (NaN: none)
  double capacity_sd_ah = 0.0;    ///< its 1-sigma; on the bus in mAh (NaN: none)
};

struct BmsStatus {
  std::uint8_t status_bits = 0;
  std::uint8_t fault_bits = 0;
  std::uint32_t tick_count = 0;
};

struct BmsRxStats {
  std::uint8_t drop_length = 0;  ///< all counters mod 256
  std::uint8_t drop_crc = 0;
  std::uint8_t drop_counter = 0;
  std::uint8_t ignored_ids = 0;
  std::uint8_t lost_frames = 0;
  std::uint8_t ticks_without_meas = 0;  ///< saturates at 255
};

inline constexpr std::uint8_t kCounterMask = 0x0F;

// ---------------------------------------------------------------------------------------
// Bindings. MessageTraits<M>::kMsg names the table row; fields(m, f) calls f on every
// member in signal order (m may be const for packing).

template <class M>
struct MessageTraits;

template <>
struct MessageTraits<Control> {
  static constexpr Msg kMsg = Msg::control;
  template <class C, class F>
  static void fields(C& m, F&& f) {
    f(m.reset_estimator), f(m.lockstep), f(m.tick_trigger), f(m.tick);
  }
};

template <>
struct MessageTraits<Measurement> {
  static constexpr Msg kMsg = Msg::measurement;
  template <class C, class F>
  static void fields(C& m, F&& f) {
    f(m.seq), f(m.voltage_v), f(m.current_a);
  }
};

template <>
struct MessageTraits<Temperature> {
  static constexpr Msg kMsg = Msg::temperature;
  template <class C, class F>
  static void fields(C& m, F&& f) {
    f(m.temperature_k);
  }
};

template <>
struct MessageTraits<Estimate1> {
  static constexpr Msg kMsg = Msg::estimate1;
  template <class C, class F>
  static void fields(C& m, F&& f) {
    f(m.seq), f(m.r_film_ohm_m2), f(m.mode), f(m.rcsi_active), f(m.valid);
  }
};

template <>
struct MessageTraits<Estimate2> {
  static constexpr Msg kMsg = Msg::estimate2;
  template <class C, class F>
  static void fields(C& m, F&& f) {
    f(m.seq), f(m.theta0);
  }
};

template <>
struct MessageTraits<Estimate3> {
  static constexpr Msg kMsg = Msg::estimate3;
  template <class C, class F>
  static void fields(C& m, F&& f) {
    f(m.seq), f(m.theta1);
  }
};

template <>
struct MessageTraits<Health> {
  static constexpr Msg kMsg = Msg::health;
  template <class C, class F>
  static void fields(C& m, F&& f) {
    f(m.seq), f(m.li_loss_ah), f(m.z_v);
  }
};

template <>
struct MessageTraits<Uncertainty> {
  static constexpr Msg kMsg = Msg::uncertainty;
  template <class C, class F>
  static void fields(C& m, F&& f) {
    f(m.seq), f(m.r_film_sd_ohm_m2), f(m.capacity_ah), f(m.capacity_sd_ah);
  }
};

template <>
struct MessageTraits<BmsStatus> {
  static constexpr Msg kMsg = Msg::status;
  template <class C, class F>
  static void fields(C& m, F&& f) {
    f(m.status_bits), f(m.fault_bits), f(m.tick_count);
  }
};

template <>
struct MessageTraits<BmsRxStats> {
  static constexpr Msg kMsg = Msg::rx_stats;
  template <class C, class F>
  static void fields(C& m, F&& f) {
    f(m.drop_length), f(m.drop_crc), f(m.drop_counter), f(m.ignored_ids), f(m.lost_frames), f(m.ticks_without_meas);
  }
};

}  // namespace bms::fw::can
