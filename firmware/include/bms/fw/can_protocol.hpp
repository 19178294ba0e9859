// The BMS CAN protocol: message identifiers, signal layout and scaling, encode/decode of
// every message, the alive counter and CRC, and a validating receiver.
//
// firmware/can/bms.dbc describes exactly this layout; tests/hal checks the DBC against
// the kMessages table below, which is also what the encoders and decoders use.
//
// Conventions
// - Classic CAN, 11-bit identifiers, little-endian (Intel, DBC "@1") signals; a signal's
//   start bit is the frame bit of its least significant bit (bit n = byte n/8, bit n%8).
// - Every frame: byte 0 = CRC-8/SAE-J1850 over the id and bytes 1..len-1 (can_crc.hpp);
//   bits 8..11 = 4-bit alive counter, +1 (mod 16) per frame sent of that message.
// - Host -> BMS messages carry Seq = tick number mod 4096; BMS -> host estimate messages
//   carry the Seq of the tick they were computed in.
// - Physical values in the C++ structs are SI (voltage_v, li_loss_ah, z_v); the DBC's
//   units are those of its factor (V, A, K, ohm.m2, mAh, uV).
// - Encoding rounds to the nearest step and saturates at the signal's raw range; NaN
//   encodes as raw 0.
//
// Header-only C++17: no heap, no exceptions, no RTTI; usable on a Cortex-M.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "bms/fw/can_crc.hpp"
#include "bms/fw/can_sequence.hpp"

#include "bms/fw/operating_mode.hpp"

namespace bms::fw::can {

// ---------------------------------------------------------------------------------------
// Layout description (exported for the DBC-vs-code test and for host tools)

enum class Node : std::uint8_t { bms, host };
enum class ValueType : std::uint8_t { unsigned_int, signed_int, float32 };

struct SignalLayout {
  const char* name;
  std::uint8_t start_bit;  ///< Intel: frame bit index of the LSB
  std::uint8_t length;     ///< bits
  ValueType type;
  double factor;  ///< physical (DBC unit) = raw * factor + offset
  double offset;
  double min;  ///< physical range in DBC units; 0, 0 for float signals (unbounded)
  double max;
  const char* unit;
};

/// All signals are little-endian (Intel); kept as a constant so the test can check it.
inline constexpr bool kSignalsLittleEndian = true;

struct MessageLayout {
  const char* name;
  std::uint32_t id;
  std::uint8_t dlc;
  Node sender;
  Node receiver;
  const SignalLayout* signals;
  std::size_t signal_count;
};

namespace sig {
// Every message: CRC and alive counter at fixed positions.
inline constexpr SignalLayout kCrc{"Crc", 0, 8, ValueType::unsigned_int, 1.0, 0.0, 0.0, 255.0, ""};
inline constexpr SignalLayout kCounter{"Counter", 8, 4, ValueType::unsigned_int, 1.0, 0.0, 0.0, 15.0, ""};
// Tick number mod 4096, bits 12..23 wherever present.
inline constexpr SignalLayout kSeq{"Seq", 12, 12, ValueType::unsigned_int, 1.0, 0.0, 0.0, 4095.0, ""};

// HOST_Control
inline constexpr SignalLayout kCtlResetEstimator{"ResetEstimator", 12, 1, ValueType::unsigned_int, 1.0, 0.0, 0.0, 1.0, ""};
inline constexpr SignalLayout kCtlLockstep{"Lockstep", 13, 1, ValueType::unsigned_int, 1.0, 0.0, 0.0, 1.0, ""};
inline constexpr SignalLayout kCtlTickTrigger{"TickTrigger", 14, 1, ValueType::unsigned_int, 1.0, 0.0, 0.0, 1.0, ""};
inline constexpr SignalLayout kCtlModeHint{"ModeHint", 16, 4, ValueType::unsigned_int, 1.0, 0.0, 0.0, 15.0, ""};
inline constexpr SignalLayout kCtlTick{"Tick", 32, 32, ValueType::unsigned_int, 1.0, 0.0, 0.0, 4294967295.0, ""};

// HOST_Measurement: 10 uV and 0.1 mA steps.
inline constexpr SignalLayout kMeasVoltage{"Voltage", 24, 20, ValueType::unsigned_int, 1e-5, 0.0, 0.0, 10.48575, "V"};
inline constexpr SignalLayout kMeasCurrent{"Current", 44, 20, ValueType::signed_int, 1e-4, 0.0, -52.4288, 52.4287, "A"};

// HOST_Temperature
inline constexpr SignalLayout kTemperature{"Temperature", 16, 16, ValueType::unsigned_int, 0.01, 0.0, 0.0, 655.35, "K"};

// BMS_Estimate1
inline constexpr SignalLayout kRFilm{"RFilm", 24, 32, ValueType::unsigned_int, 1e-10, 0.0, 0.0, 0.4294967295, "ohm.m2"};
inline constexpr SignalLayout kEstMode{"Mode", 56, 4, ValueType::unsigned_int, 1.0, 0.0, 0.0, 15.0, ""};
inline constexpr SignalLayout kEstRcsiActive{"RcsiActive", 60, 1, ValueType::unsigned_int, 1.0, 0.0, 0.0, 1.0, ""};
inline constexpr SignalLayout kEstValid{"EstimateValid", 61, 1, ValueType::unsigned_int, 1.0, 0.0, 0.0, 1.0, ""};

// BMS_Estimate2 / BMS_Estimate3: theta components as IEEE-754 float32.
inline constexpr SignalLayout kTheta0{"Theta0", 32, 32, ValueType::float32, 1.0, 0.0, 0.0, 0.0, ""};
inline constexpr SignalLayout kTheta1{"Theta1", 32, 32, ValueType::float32, 1.0, 0.0, 0.0, 0.0, ""};

// BMS_Health: lithium loss in 0.1 uAh steps, voltage residual z = y_hat - y in 1 uV steps.
inline constexpr SignalLayout kLiLoss{"LiLoss", 24, 24, ValueType::unsigned_int, 1e-4, 0.0, 0.0, 1677.7215, "mAh"};
inline constexpr SignalLayout kZResidual{"ZResidual", 48, 16, ValueType::signed_int, 1.0, 0.0, -32768.0, 32767.0, "uV"};

// BMS_Status
inline constexpr SignalLayout kStatusBits{"StatusBits", 12, 8, ValueType::unsigned_int, 1.0, 0.0, 0.0, 255.0, ""};
inline constexpr SignalLayout kFaultBits{"FaultBits", 20, 8, ValueType::unsigned_int, 1.0, 0.0, 0.0, 255.0, ""};
inline constexpr SignalLayout kTickCount{"TickCount", 32, 32, ValueType::unsigned_int, 1.0, 0.0, 0.0, 4294967295.0, ""};

// BMS_RxStats: receive counters mod 256 (the host takes differences), staleness saturated.
inline constexpr SignalLayout kDropLength{"DropLength", 16, 8, ValueType::unsigned_int, 1.0, 0.0, 0.0, 255.0, ""};
inline constexpr SignalLayout kDropCrc{"DropCrc", 24, 8, ValueType::unsigned_int, 1.0, 0.0, 0.0, 255.0, ""};
inline constexpr SignalLayout kDropCounter{"DropCounter", 32, 8, ValueType::unsigned_int, 1.0, 0.0, 0.0, 255.0, ""};
inline constexpr SignalLayout kIgnoredIds{"IgnoredIds", 40, 8, ValueType::unsigned_int, 1.0, 0.0, 0.0, 255.0, ""};
inline constexpr SignalLayout kLostFrames{"LostFrames", 48, 8, ValueType::unsigned_int, 1.0, 0.0, 0.0, 255.0, ""};
inline constexpr SignalLayout kTicksWithoutMeas{"TicksWithoutMeas", 56, 8, ValueType::unsigned_int, 1.0, 0.0, 0.0, 255.0, ""};
}  // namespace sig

inline constexpr SignalLayout kControlSignals[] = {sig::kCrc, sig::kCounter, sig::kCtlResetEstimator,
                                                   sig::kCtlLockstep, sig::kCtlTickTrigger, sig::kCtlModeHint,
                                                   sig::kCtlTick};
inline constexpr SignalLayout kMeasurementSignals[] = {sig::kCrc, sig::kCounter, sig::kSeq, sig::kMeasVoltage,
                                                       sig::kMeasCurrent};
inline constexpr SignalLayout kTemperatureSignals[] = {sig::kCrc, sig::kCounter, sig::kTemperature};
inline constexpr SignalLayout kEstimate1Signals[] = {sig::kCrc,     sig::kCounter,        sig::kSeq,     sig::kRFilm,
                                                     sig::kEstMode, sig::kEstRcsiActive, sig::kEstValid};
inline constexpr SignalLayout kEstimate2Signals[] = {sig::kCrc, sig::kCounter, sig::kSeq, sig::kTheta0};
inline constexpr SignalLayout kEstimate3Signals[] = {sig::kCrc, sig::kCounter, sig::kSeq, sig::kTheta1};
inline constexpr SignalLayout kHealthSignals[] = {sig::kCrc, sig::kCounter, sig::kSeq, sig::kLiLoss,
                                                  sig::kZResidual};
inline constexpr SignalLayout kStatusSignals[] = {sig::kCrc, sig::kCounter, sig::kStatusBits, sig::kFaultBits,
                                                  sig::kTickCount};
inline constexpr SignalLayout kRxStatsSignals[] = {sig::kCrc,         sig::kCounter,     sig::kDropLength,
                                                   sig::kDropCrc,     sig::kDropCounter, sig::kIgnoredIds,
                                                   sig::kLostFrames,  sig::kTicksWithoutMeas};

/// Index of a message in kMessages.
enum class Msg : std::uint8_t {
  control = 0,
  measurement,
  temperature,
  estimate1,
  estimate2,
  estimate3,
  health,
  status,
  rx_stats,
};
inline constexpr std::size_t kMessageCount = 9;

namespace id {
inline constexpr std::uint32_t kControl = 0x100;
inline constexpr std::uint32_t kMeasurement = 0x110;
inline constexpr std::uint32_t kTemperature = 0x111;
inline constexpr std::uint32_t kEstimate1 = 0x200;
inline constexpr std::uint32_t kEstimate2 = 0x201;
inline constexpr std::uint32_t kEstimate3 = 0x202;
inline constexpr std::uint32_t kHealth = 0x203;
inline constexpr std::uint32_t kStatus = 0x210;
inline constexpr std::uint32_t kRxStats = 0x211;
}  // namespace id

template <std::size_t N>
constexpr MessageLayout make_layout(const char* name, std::uint32_t msg_id, std::uint8_t dlc, Node sender,
                                    Node receiver, const SignalLayout (&signals)[N]) {
  return MessageLayout{name, msg_id, dlc, sender, receiver, signals, N};
}

inline constexpr MessageLayout kMessages[kMessageCount] = {
    make_layout("HOST_Control", id::kControl, 8, Node::host, Node::bms, kControlSignals),
    make_layout("HOST_Measurement", id::kMeasurement, 8, Node::host, Node::bms, kMeasurementSignals),
    make_layout("HOST_Temperature", id::kTemperature, 4, Node::host, Node::bms, kTemperatureSignals),
    make_layout("BMS_Estimate1", id::kEstimate1, 8, Node::bms, Node::host, kEstimate1Signals),
    make_layout("BMS_Estimate2", id::kEstimate2, 8, Node::bms, Node::host, kEstimate2Signals),
    make_layout("BMS_Estimate3", id::kEstimate3, 8, Node::bms, Node::host, kEstimate3Signals),
    make_layout("BMS_Health", id::kHealth, 8, Node::bms, Node::host, kHealthSignals),
    make_layout("BMS_Status", id::kStatus, 8, Node::bms, Node::host, kStatusSignals),
    make_layout("BMS_RxStats", id::kRxStats, 8, Node::bms, Node::host, kRxStatsSignals),
};

constexpr const MessageLayout& layout(Msg m) { return kMessages[static_cast<std::size_t>(m)]; }

/// Index into kMessages of the message with this identifier, or -1.
constexpr int message_index(std::uint32_t can_id) {
  for (std::size_t i = 0; i < kMessageCount; ++i)
    if (kMessages[i].id == can_id) return static_cast<int>(i);
  return -1;
}

// ---------------------------------------------------------------------------------------
// Values

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
inline constexpr std::uint8_t kInternal = 1u << 7;       ///< core call-order/config fault, a failed send, a refused reset
}  // namespace fault_bit

struct Control {
  bool reset_estimator = false;  ///< back to the power-on state (bms::app::BmsApplication)
  bool lockstep = false;         ///< 1: the host drives ticks (the firmware ignores its timer)
  bool tick_trigger = false;     ///< 1: this frame triggers tick `tick` (lock-step)
  Mode mode_hint = Mode::unknown;
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

inline constexpr double kMahPerAh = 1000.0;
inline constexpr double kUvPerV = 1e6;
inline constexpr std::uint8_t kCounterMask = 0x0F;

// ---------------------------------------------------------------------------------------
// Bit packing (Intel)

constexpr void put_bits(std::uint8_t* data, unsigned start, unsigned len, std::uint64_t raw) {
  for (unsigned i = 0; i < len; ++i) {
    const unsigned bit = start + i;
    const auto mask = static_cast<std::uint8_t>(1u << (bit % 8u));
    if (((raw >> i) & 1u) != 0u)
      data[bit / 8u] = static_cast<std::uint8_t>(data[bit / 8u] | mask);
    else
      data[bit / 8u] = static_cast<std::uint8_t>(data[bit / 8u] & static_cast<std::uint8_t>(~mask));
  }
}

constexpr std::uint64_t get_bits(const std::uint8_t* data, unsigned start, unsigned len) {
  std::uint64_t raw = 0;
  for (unsigned i = 0; i < len; ++i) {
    const unsigned bit = start + i;
    if (((data[bit / 8u] >> (bit % 8u)) & 1u) != 0u) raw |= (std::uint64_t{1} << i);
  }
  return raw;
}

constexpr std::int64_t sign_extend(std::uint64_t raw, unsigned len) {
  const std::uint64_t sign = std::uint64_t{1} << (len - 1u);
  const std::uint64_t value = raw & ((sign << 1u) - 1u);
  return (value & sign) != 0u ? static_cast<std::int64_t>(value) - static_cast<std::int64_t>(sign << 1u)
                              : static_cast<std::int64_t>(value);
}

/// Smallest and largest raw integer of a signal (as signed values).
constexpr std::int64_t raw_min(const SignalLayout& s) {
  // The analyzer assumes a signal of length 0 (shift by -1): every SignalLayout in this file
  // has length 1..32, and tests/hal checks the table against the DBC.
  // NOLINTNEXTLINE(clang-analyzer-core.UndefinedBinaryOperatorResult)
  return s.type == ValueType::signed_int ? -(std::int64_t{1} << (s.length - 1u)) : 0;
}
constexpr std::int64_t raw_max(const SignalLayout& s) {
  return s.type == ValueType::signed_int ? (std::int64_t{1} << (s.length - 1u)) - 1
                                         : static_cast<std::int64_t>((std::uint64_t{1} << s.length) - 1u);
}

/// Physical value (DBC unit) -> raw integer: nearest step, saturated. NaN -> the end of the
/// raw range a receiver's plausibility check rejects (unsigned: the largest raw value, e.g.
/// 10.49 V; signed: the most negative, e.g. -52.4 A), never 0, which reads as a plausible 0 A.
inline std::int64_t to_raw(const SignalLayout& s, double physical) {
  if (std::isnan(physical)) return s.type == ValueType::signed_int ? raw_min(s) : raw_max(s);
  const double scaled = (physical - s.offset) / s.factor;
  const auto lo = static_cast<double>(raw_min(s));
  const auto hi = static_cast<double>(raw_max(s));
  if (scaled <= lo) return raw_min(s);
  if (scaled >= hi) return raw_max(s);
  const double r = scaled >= 0.0 ? std::floor(scaled + 0.5) : std::ceil(scaled - 0.5);
  return static_cast<std::int64_t>(r);
}

constexpr double from_raw(const SignalLayout& s, std::int64_t raw) {
  return static_cast<double>(raw) * s.factor + s.offset;
}

/// Write a scaled integer signal.
inline void put_physical(std::uint8_t* data, const SignalLayout& s, double physical) {
  put_bits(data, s.start_bit, s.length, static_cast<std::uint64_t>(to_raw(s, physical)));
}

/// Read a scaled integer signal.
constexpr double get_physical(const std::uint8_t* data, const SignalLayout& s) {
  const std::uint64_t raw = get_bits(data, s.start_bit, s.length);
  return s.type == ValueType::signed_int ? from_raw(s, sign_extend(raw, s.length))
                                         : from_raw(s, static_cast<std::int64_t>(raw));
}

inline void put_uint(std::uint8_t* data, const SignalLayout& s, std::uint64_t raw) {
  put_bits(data, s.start_bit, s.length, raw);
}
constexpr std::uint64_t get_uint(const std::uint8_t* data, const SignalLayout& s) {
  return get_bits(data, s.start_bit, s.length);
}

inline void put_float32(std::uint8_t* data, const SignalLayout& s, float value) {
  std::uint32_t bits = 0;
  std::memcpy(&bits, &value, sizeof bits);
  put_bits(data, s.start_bit, 32, bits);
}
inline float get_float32(const std::uint8_t* data, const SignalLayout& s) {
  const auto bits = static_cast<std::uint32_t>(get_bits(data, s.start_bit, 32));
  float value = 0.0f;
  std::memcpy(&value, &bits, sizeof value);
  return value;
}

// ---------------------------------------------------------------------------------------
// Per-message packing. MessageTraits<M>::pack writes the message's signals (not CRC and
// counter) into a zeroed payload; unpack reads them.

template <class M>
struct MessageTraits;

template <>
struct MessageTraits<Control> {
  static constexpr Msg kMsg = Msg::control;
  static void pack(const Control& m, std::uint8_t* d) {
    put_uint(d, sig::kCtlResetEstimator, m.reset_estimator ? 1u : 0u);
    put_uint(d, sig::kCtlLockstep, m.lockstep ? 1u : 0u);
    put_uint(d, sig::kCtlTickTrigger, m.tick_trigger ? 1u : 0u);
    put_uint(d, sig::kCtlModeHint, static_cast<std::uint64_t>(m.mode_hint));
    put_uint(d, sig::kCtlTick, m.tick);
  }
  static void unpack(const std::uint8_t* d, Control& m) {
    m.reset_estimator = get_uint(d, sig::kCtlResetEstimator) != 0u;
    m.lockstep = get_uint(d, sig::kCtlLockstep) != 0u;
    m.tick_trigger = get_uint(d, sig::kCtlTickTrigger) != 0u;
    m.mode_hint = mode_from_raw(get_uint(d, sig::kCtlModeHint));
    m.tick = static_cast<std::uint32_t>(get_uint(d, sig::kCtlTick));
  }
};

template <>
struct MessageTraits<Measurement> {
  static constexpr Msg kMsg = Msg::measurement;
  static void pack(const Measurement& m, std::uint8_t* d) {
    put_uint(d, sig::kSeq, m.seq & kSeqMask);
    put_physical(d, sig::kMeasVoltage, m.voltage_v);
    put_physical(d, sig::kMeasCurrent, m.current_a);
  }
  static void unpack(const std::uint8_t* d, Measurement& m) {
    m.seq = static_cast<std::uint16_t>(get_uint(d, sig::kSeq));
    m.voltage_v = get_physical(d, sig::kMeasVoltage);
    m.current_a = get_physical(d, sig::kMeasCurrent);
  }
};

template <>
struct MessageTraits<Temperature> {
  static constexpr Msg kMsg = Msg::temperature;
  static void pack(const Temperature& m, std::uint8_t* d) { put_physical(d, sig::kTemperature, m.temperature_k); }
  static void unpack(const std::uint8_t* d, Temperature& m) { m.temperature_k = get_physical(d, sig::kTemperature); }
};

template <>
struct MessageTraits<Estimate1> {
  static constexpr Msg kMsg = Msg::estimate1;
  static void pack(const Estimate1& m, std::uint8_t* d) {
    put_uint(d, sig::kSeq, m.seq & kSeqMask);
    put_physical(d, sig::kRFilm, m.r_film_ohm_m2);
    put_uint(d, sig::kEstMode, static_cast<std::uint64_t>(m.mode));
    put_uint(d, sig::kEstRcsiActive, m.rcsi_active ? 1u : 0u);
    put_uint(d, sig::kEstValid, m.valid ? 1u : 0u);
  }
  static void unpack(const std::uint8_t* d, Estimate1& m) {
    m.seq = static_cast<std::uint16_t>(get_uint(d, sig::kSeq));
    m.r_film_ohm_m2 = get_physical(d, sig::kRFilm);
    m.mode = mode_from_raw(get_uint(d, sig::kEstMode));
    m.rcsi_active = get_uint(d, sig::kEstRcsiActive) != 0u;
    m.valid = get_uint(d, sig::kEstValid) != 0u;
  }
};

template <>
struct MessageTraits<Estimate2> {
  static constexpr Msg kMsg = Msg::estimate2;
  static void pack(const Estimate2& m, std::uint8_t* d) {
    put_uint(d, sig::kSeq, m.seq & kSeqMask);
    put_float32(d, sig::kTheta0, m.theta0);
  }
  static void unpack(const std::uint8_t* d, Estimate2& m) {
    m.seq = static_cast<std::uint16_t>(get_uint(d, sig::kSeq));
    m.theta0 = get_float32(d, sig::kTheta0);
  }
};

template <>
struct MessageTraits<Estimate3> {
  static constexpr Msg kMsg = Msg::estimate3;
  static void pack(const Estimate3& m, std::uint8_t* d) {
    put_uint(d, sig::kSeq, m.seq & kSeqMask);
    put_float32(d, sig::kTheta1, m.theta1);
  }
  static void unpack(const std::uint8_t* d, Estimate3& m) {
    m.seq = static_cast<std::uint16_t>(get_uint(d, sig::kSeq));
    m.theta1 = get_float32(d, sig::kTheta1);
  }
};

template <>
struct MessageTraits<Health> {
  static constexpr Msg kMsg = Msg::health;
  static void pack(const Health& m, std::uint8_t* d) {
    put_uint(d, sig::kSeq, m.seq & kSeqMask);
    put_physical(d, sig::kLiLoss, m.li_loss_ah * kMahPerAh);
    put_physical(d, sig::kZResidual, m.z_v * kUvPerV);
  }
  static void unpack(const std::uint8_t* d, Health& m) {
    m.seq = static_cast<std::uint16_t>(get_uint(d, sig::kSeq));
    m.li_loss_ah = get_physical(d, sig::kLiLoss) / kMahPerAh;
    m.z_v = get_physical(d, sig::kZResidual) / kUvPerV;
  }
};

template <>
struct MessageTraits<BmsStatus> {
  static constexpr Msg kMsg = Msg::status;
  static void pack(const BmsStatus& m, std::uint8_t* d) {
    put_uint(d, sig::kStatusBits, m.status_bits);
    put_uint(d, sig::kFaultBits, m.fault_bits);
    put_uint(d, sig::kTickCount, m.tick_count);
  }
  static void unpack(const std::uint8_t* d, BmsStatus& m) {
    m.status_bits = static_cast<std::uint8_t>(get_uint(d, sig::kStatusBits));
    m.fault_bits = static_cast<std::uint8_t>(get_uint(d, sig::kFaultBits));
    m.tick_count = static_cast<std::uint32_t>(get_uint(d, sig::kTickCount));
  }
};

template <>
struct MessageTraits<BmsRxStats> {
  static constexpr Msg kMsg = Msg::rx_stats;
  static void pack(const BmsRxStats& m, std::uint8_t* d) {
    put_uint(d, sig::kDropLength, m.drop_length);
    put_uint(d, sig::kDropCrc, m.drop_crc);
    put_uint(d, sig::kDropCounter, m.drop_counter);
    put_uint(d, sig::kIgnoredIds, m.ignored_ids);
    put_uint(d, sig::kLostFrames, m.lost_frames);
    put_uint(d, sig::kTicksWithoutMeas, m.ticks_without_meas);
  }
  static void unpack(const std::uint8_t* d, BmsRxStats& m) {
    m.drop_length = static_cast<std::uint8_t>(get_uint(d, sig::kDropLength));
    m.drop_crc = static_cast<std::uint8_t>(get_uint(d, sig::kDropCrc));
    m.drop_counter = static_cast<std::uint8_t>(get_uint(d, sig::kDropCounter));
    m.ignored_ids = static_cast<std::uint8_t>(get_uint(d, sig::kIgnoredIds));
    m.lost_frames = static_cast<std::uint8_t>(get_uint(d, sig::kLostFrames));
    m.ticks_without_meas = static_cast<std::uint8_t>(get_uint(d, sig::kTicksWithoutMeas));
  }
};

// ---------------------------------------------------------------------------------------
// Frame-level encode/decode. FrameT is any struct with members `id` (uint32_t),
// `len` (uint8_t) and `data` (uint8_t[8]), e.g. bms::hal::CanFrame.

/// Fill `frame` with message `m`, alive counter `counter` (mod 16) and the CRC.
template <class M, class FrameT>
void encode(const M& m, std::uint8_t counter, FrameT& frame) {
  const MessageLayout& l = layout(MessageTraits<M>::kMsg);
  frame.id = l.id;
  frame.len = l.dlc;
  for (auto& b : frame.data) b = 0;
  MessageTraits<M>::pack(m, frame.data);
  put_uint(frame.data, sig::kCounter, counter & kCounterMask);
  frame.data[0] = frame_crc(frame.id, frame.data, frame.len);
}

/// Decode the signals of `frame` into `m` when id and length match M; no CRC or
/// counter check (use Receiver for that). Returns false on a mismatch.
template <class M, class FrameT>
bool decode(const FrameT& frame, M& m) {
  const MessageLayout& l = layout(MessageTraits<M>::kMsg);
  if (frame.id != l.id || frame.len != l.dlc) return false;
  MessageTraits<M>::unpack(frame.data, m);
  return true;
}

constexpr std::uint8_t frame_counter(const std::uint8_t* data) {
  return static_cast<std::uint8_t>(get_bits(data, sig::kCounter.start_bit, sig::kCounter.length));
}

template <class FrameT>
constexpr bool frame_crc_ok(const FrameT& frame) {
  return frame.len >= 1u && frame.data[0] == frame_crc(frame.id, frame.data, frame.len);
}

/// Keeps one alive counter per message and encodes frames with it.
class Transmitter {
 public:
  template <class M, class FrameT>
  void encode(const M& m, FrameT& frame) {
    auto& c = counters_[static_cast<std::size_t>(MessageTraits<M>::kMsg)];
    can::encode(m, c, frame);
    c = static_cast<std::uint8_t>((c + 1u) & kCounterMask);
  }
  std::uint8_t next_counter(Msg m) const { return counters_[static_cast<std::size_t>(m)]; }
  void reset() {
    for (auto& c : counters_) c = 0;
  }

 private:
  std::uint8_t counters_[kMessageCount]{};
};

// ---------------------------------------------------------------------------------------
// Receiver: validates and counts.

enum class RxResult : std::uint8_t {
  accepted,
  ignored_id,       ///< unknown id, or a message not addressed to this node: not an error
  dropped_length,   ///< known id with the wrong data length
  dropped_crc,      ///< CRC mismatch
  dropped_counter,  ///< alive counter repeated (frozen) or jumped backwards / too far
  dropped_seq,      ///< HOST_Measurement whose Seq lies outside the tick's window (stale, replayed, early)
};

constexpr const char* rx_result_name(RxResult r) {
  switch (r) {
    case RxResult::accepted: return "accepted";
    case RxResult::ignored_id: return "ignored_id";
    case RxResult::dropped_length: return "dropped_length";
    case RxResult::dropped_crc: return "dropped_crc";
    case RxResult::dropped_counter: return "dropped_counter";
    case RxResult::dropped_seq: return "dropped_seq";
  }
  return "unknown";
}

struct RxCounters {
  std::uint32_t accepted = 0;
  std::uint32_t ignored_id = 0;
  std::uint32_t dropped_length = 0;
  std::uint32_t dropped_crc = 0;
  std::uint32_t dropped_counter = 0;
  std::uint32_t dropped_seq = 0;   ///< measurements outside the sequence window (set_seq_window)
  std::uint32_t lost_frames = 0;   ///< frames inferred missing from accepted counter gaps
  std::uint32_t stale_events = 0;  ///< times the watched message became stale

  constexpr std::uint32_t dropped_total() const { return dropped_length + dropped_crc + dropped_counter + dropped_seq; }
};

/// The message decoded by Receiver::accept; only the member named by `msg` is set.
struct RxMessage {
  Msg msg = Msg::control;
  Control control;
  Measurement measurement;
  Temperature temperature;
  Estimate1 estimate1;
  Estimate2 estimate2;
  Estimate3 estimate3;
  Health health;
  BmsStatus status;
  BmsRxStats rx_stats;
};

/// Largest accepted alive-counter step: 1 is the normal case, 2..7 mean 1..6 frames were
/// lost (accepted, counted in lost_frames); 0 (repeated/frozen) and 8..15 (old or
/// reordered frame) are dropped. After a drop for a step of 8..15 the receiver resyncs on
/// that counter, so a restarted sender costs one frame.
inline constexpr std::uint8_t kMaxCounterStep = 7;

/// The watched message is stale once it has been missing for more than this many ticks.
inline constexpr std::uint32_t kMaxMissingTicks = 2;

class Receiver {
 public:
  /// `self`: the node this receiver runs on; it accepts the messages addressed to it.
  /// The watched message (for staleness) is HOST_Measurement on the BMS, BMS_Status on
  /// the host.
  explicit Receiver(Node self = Node::bms)
      : self_(self), watched_(self == Node::bms ? Msg::measurement : Msg::status) {}

  /// Validate one frame: id (ignored when unknown or not for this node), length, CRC,
  /// alive counter, in that order; decode it into `out` when accepted.
  RxResult accept(std::uint32_t can_id, const std::uint8_t* data, std::uint8_t len, RxMessage& out) {
    const int idx = message_index(can_id);
    if (idx < 0 || kMessages[idx].receiver != self_) {
      ++counters_.ignored_id;
      return RxResult::ignored_id;
    }
    const MessageLayout& l = kMessages[idx];
    if (len != l.dlc) {
      ++counters_.dropped_length;
      return RxResult::dropped_length;
    }
    if (data[0] != frame_crc(can_id, data, len)) {
      ++counters_.dropped_crc;
      return RxResult::dropped_crc;
    }
    if (static_cast<Msg>(idx) == Msg::measurement && !seq_in_window(data)) {
      ++counters_.dropped_seq;
      last_rejected_seq_ = static_cast<std::uint16_t>(get_uint(data, sig::kSeq));
      return RxResult::dropped_seq;
    }
    const std::uint8_t c = frame_counter(data);
    CounterState& st = counter_state_[idx];
    if (st.seen) {
      const auto step = static_cast<std::uint8_t>((c - st.last) & kCounterMask);
      if (step == 0u) {
        ++counters_.dropped_counter;
        return RxResult::dropped_counter;
      }
      if (step > kMaxCounterStep) {
        st.last = c;  // resync
        ++counters_.dropped_counter;
        return RxResult::dropped_counter;
      }
      counters_.lost_frames += static_cast<std::uint32_t>(step - 1u);
    }
    st.seen = true;
    st.last = c;
    ++counters_.accepted;

    out.msg = static_cast<Msg>(idx);
    switch (out.msg) {
      case Msg::control: MessageTraits<Control>::unpack(data, out.control); break;
      case Msg::measurement: MessageTraits<Measurement>::unpack(data, out.measurement); break;
      case Msg::temperature: MessageTraits<Temperature>::unpack(data, out.temperature); break;
      case Msg::estimate1: MessageTraits<Estimate1>::unpack(data, out.estimate1); break;
      case Msg::estimate2: MessageTraits<Estimate2>::unpack(data, out.estimate2); break;
      case Msg::estimate3: MessageTraits<Estimate3>::unpack(data, out.estimate3); break;
      case Msg::health: MessageTraits<Health>::unpack(data, out.health); break;
      case Msg::status: MessageTraits<BmsStatus>::unpack(data, out.status); break;
      case Msg::rx_stats: MessageTraits<BmsRxStats>::unpack(data, out.rx_stats); break;
    }
    if (out.msg == watched_) {
      watched_seen_ = true;
      missing_ticks_ = 0;
    }
    return RxResult::accepted;
  }

  template <class FrameT>
  RxResult accept(const FrameT& frame, RxMessage& out) {
    return accept(frame.id, frame.data, frame.len, out);
  }

  /// Call once per tick, after the tick's frames were accepted: counts the ticks in a row
  /// without a valid watched message.
  void on_tick() {
    if (!watched_seen_ && missing_ticks_ < UINT32_MAX) {
      ++missing_ticks_;
      if (missing_ticks_ == kMaxMissingTicks + 1u) ++counters_.stale_events;
    }
    watched_seen_ = false;
  }

  /// Staleness counter: ticks in a row without a valid watched message (0 after one).
  std::uint32_t ticks_without_measurement() const { return missing_ticks_; }
  /// True once the watched message has been missing for more than kMaxMissingTicks
  /// ticks; false again as soon as a valid one is accepted.
  bool measurement_stale() const { return missing_ticks_ > kMaxMissingTicks; }

  const RxCounters& counters() const { return counters_; }

  /// The BMS_RxStats message for these counters (mod 256; staleness saturated).
  BmsRxStats rx_stats() const {
    BmsRxStats s;
    s.drop_length = static_cast<std::uint8_t>(counters_.dropped_length & 0xFFu);
    s.drop_crc = static_cast<std::uint8_t>(counters_.dropped_crc & 0xFFu);
    // DropCounter: alive-counter and sequence-window drops (both say "not this tick's frame").
    s.drop_counter = static_cast<std::uint8_t>((counters_.dropped_counter + counters_.dropped_seq) & 0xFFu);
    s.ignored_ids = static_cast<std::uint8_t>(counters_.ignored_id & 0xFFu);
    s.lost_frames = static_cast<std::uint8_t>(counters_.lost_frames & 0xFFu);
    s.ticks_without_meas = static_cast<std::uint8_t>(missing_ticks_ > 255u ? 255u : missing_ticks_);
    return s;
  }

  /// Forget counters, alive-counter history, staleness and the sequence window.
  void reset() { *this = Receiver(self_); }

  /// Sequence window of HOST_Measurement, set by the application before it drains a tick's
  /// frames: only Seq = first, first + 1, ..., first + count - 1 (mod 4096) passes; count 0
  /// lets none pass. The check comes before the alive counter's, so an old or replayed frame
  /// with a plausible counter is dropped (dropped_seq) without pushing the genuine frame out.
  void set_seq_window(std::uint16_t first, std::uint16_t count) {
    window_on_ = true;
    window_first_ = static_cast<std::uint16_t>(first & kSeqMask);
    window_count_ = count;
  }
  /// Every Seq passes (the default; the host side).
  void clear_seq_window() { window_on_ = false; }
  /// Seq of the last measurement dropped by the window (for the resynchronisation rule).
  std::uint16_t last_rejected_seq() const { return last_rejected_seq_; }

 private:
  struct CounterState {
    bool seen = false;
    std::uint8_t last = 0;
  };
  Node self_;
  Msg watched_;
  CounterState counter_state_[kMessageCount]{};
  RxCounters counters_{};
  bool seq_in_window(const std::uint8_t* data) const {
    if (!window_on_) return true;
    const auto seq = static_cast<std::uint32_t>(get_uint(data, sig::kSeq));
    return ((seq - window_first_) & kSeqMask) < window_count_;
  }

  bool watched_seen_ = false;
  std::uint32_t missing_ticks_ = 0;
  bool window_on_ = false;
  std::uint16_t window_first_ = 0;
  std::uint16_t window_count_ = 0;
  std::uint16_t last_rejected_seq_ = 0;
};

// ---------------------------------------------------------------------------------------
// Lock-step ticks

/// Recognises the frames that trigger a tick in lock-step mode, for bms::hal::LockstepBus.
/// Both trigger kinds carry the host's sequence number, followed by SeqTracker
/// (can_sequence.hpp) with a window of kMaxTickStep:
/// - HOST_Measurement, right length, good CRC: Seq (tick number mod 4096).
/// - HOST_Control, right length, good CRC, TickTrigger = 1: Tick mod 4096 (its full 32
///   bits only for the very first trigger, when there is nothing to compare with).
/// An adopted number triggers tick = the previous adopted tick + its distance (lost trigger
/// frames are missed ticks, at most kMaxTickStep - 1 per frame). A repeat or a number behind
/// (a duplicated, reordered or replayed frame) triggers nothing: running a tick for it would
/// step the model twice for one 0.2 s of cell time. A restarted host is followed after
/// SeqTracker::kResyncFrames consecutive frames; its first tick is the next one (no gap).
/// A HOST_Measurement with the right length but a bad CRC still triggers the next tick
/// (the host did send a tick; the Receiver then drops the frame, and the tick runs with the
/// measurement missing), but at most kMaxUnconfirmedTicks in a row: a burst of corrupted
/// copies cannot run the clock ahead of the genuine frames.
/// Use with LockstepBus through a captureless lambda:
///   [](const hal::CanFrame& f, uint32_t& t, void* c) {
///     return static_cast<can::LockstepTicks*>(c)->classify(f, t); }
class LockstepTicks {
 public:
  /// Largest tick step one trigger frame may claim (10 s of 0.2 s ticks).
  static constexpr std::uint32_t kMaxTickStep = 50;
  /// Ticks a corrupted trigger may run before a frame with a good CRC must come.
  static constexpr std::uint32_t kMaxUnconfirmedTicks = 1;

  template <class FrameT>
  bool classify(const FrameT& frame, std::uint32_t& tick) {
    if (frame.id == id::kMeasurement && frame.len == layout(Msg::measurement).dlc) {
      if (!frame_crc_ok(frame)) return on_corrupted(tick);
      const auto seq = static_cast<std::uint32_t>(get_uint(frame.data, sig::kSeq));
      return on_sequence(seq, seq, tick);
    }
    if (frame.id == id::kControl && frame.len == layout(Msg::control).dlc && frame_crc_ok(frame) &&
        get_uint(frame.data, sig::kCtlTickTrigger) != 0u) {
      const auto full = static_cast<std::uint32_t>(get_uint(frame.data, sig::kCtlTick));
      return on_sequence(full & kSeqMask, full, tick);
    }
    return false;
  }

  std::uint32_t last_tick() const { return last_tick_; }
  /// The Seq a measurement of the last triggered tick must carry; false when that tick was
  /// triggered by a corrupted frame (no measurement belongs to it).
  bool tick_seq(std::uint16_t& seq) const {
    seq = seq_.last();
    return have_ && !last_unconfirmed_;
  }
  /// Good trigger frames that triggered nothing (repeats, late, too far ahead, already run).
  std::uint32_t rejected() const { return rejected_; }
  /// Corrupted trigger frames beyond kMaxUnconfirmedTicks (triggered nothing).
  std::uint32_t unconfirmed_refused() const { return unconfirmed_refused_; }
  std::uint32_t resyncs() const { return seq_.resyncs(); }

 private:
  bool on_corrupted(std::uint32_t& tick) {
    if (!have_ || unconfirmed_ >= kMaxUnconfirmedTicks) {
      ++unconfirmed_refused_;
      return false;
    }
    ++unconfirmed_;
    last_unconfirmed_ = true;
    tick = ++last_tick_;
    return true;
  }

  bool on_sequence(std::uint32_t seq, std::uint32_t first_tick, std::uint32_t& tick) {
    switch (seq_.observe(static_cast<std::uint16_t>(seq), kMaxTickStep)) {
      case SeqTracker::Verdict::first: anchor_tick_ = first_tick; break;
      case SeqTracker::Verdict::in_window:
      case SeqTracker::Verdict::jump: anchor_tick_ += seq_.step(); break;
      case SeqTracker::Verdict::restart: anchor_tick_ = last_tick_ + 1u; break;
      case SeqTracker::Verdict::rejected: ++rejected_; return false;
    }
    // A tick already run on a corrupted trigger is not run again.
    if (have_ && static_cast<std::int32_t>(anchor_tick_ - last_tick_) <= 0) {
      ++rejected_;
      return false;
    }
    have_ = true;
    unconfirmed_ = 0;
    last_unconfirmed_ = false;
    last_tick_ = anchor_tick_;
    tick = last_tick_;
    return true;
  }

  SeqTracker seq_;
  bool have_ = false;
  bool last_unconfirmed_ = false;
  std::uint32_t unconfirmed_ = 0;
  std::uint32_t last_tick_ = 0;
  std::uint32_t anchor_tick_ = 0;  // the tick of the last adopted sequence number
  std::uint32_t rejected_ = 0;
  std::uint32_t unconfirmed_refused_ = 0;
};

}  // namespace bms::fw::can
