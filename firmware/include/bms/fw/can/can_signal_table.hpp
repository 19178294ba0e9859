// The BMS CAN protocol's signal table: message identifiers, every signal's position,
// length, signedness, scaling and range, in one constexpr table (kMessages).
//
// This table is the only description of the layout in the code: the codec (can_codec.hpp)
// packs and unpacks every message by walking it, and tests/hal/test_dbc.cpp checks
// firmware/can/bms.dbc against it, so the DBC and the frames cannot drift apart.
//
// Conventions
// - Classic CAN, 11-bit identifiers, little-endian (Intel, DBC "@1") signals; a signal's
//   start bit is the frame bit of its least significant bit (bit n = byte n/8, bit n%8).
// - Every frame: byte 0 = CRC-8/SAE-J1850 over the id and bytes 1..len-1 (can_crc.hpp);
//   bits 8..11 = 4-bit alive counter, +1 (mod 16) per frame sent of that message. These
//   two framing signals come first in every message's signal list.
// - Host -> BMS messages carry Seq = tick number mod 4096; BMS -> host estimate messages
//   carry the Seq of the tick they were computed in.
// - Physical values in the C++ structs are SI (voltage_v, li_loss_ah, z_v); the DBC's
//   units are those of its factor (V, A, K, ohm.m2, mAh, uV); units_per_si converts.
//
// Header-only C++17: no heap, no exceptions, no RTTI; usable on a Cortex-M.
#pragma once

#include <cstddef>
#include <cstdint>

namespace bms::fw::can {

// ---------------------------------------------------------------------------------------
// Layout description (exported for the DBC-vs-code test and for host tools)

enum class Node : std::uint8_t { bms, host };
enum class ValueType : std::uint8_t { unsigned_int, signed_int, float32 };

/// How a signal's value reaches its raw bits.
enum class Coding : std::uint8_t {
  integer,   ///< the struct's integer/flag/enum as raw bits, wrapped to the length (Seq mod 4096)
  physical,  ///< SI value * units_per_si on the factor's grid: nearest step, saturated, NaN at a rejected end
  float32,   ///< IEEE-754 single precision, bit for bit
};

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
  Coding coding = Coding::integer;
  double units_per_si = 1.0;  ///< DBC units per SI unit of the struct member (mAh per Ah: 1000)
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

inline constexpr double kMahPerAh = 1000.0;
inline constexpr double kUvPerV = 1e6;

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
inline constexpr SignalLayout kCtlTick{"Tick", 32, 32, ValueType::unsigned_int, 1.0, 0.0, 0.0, 4294967295.0, ""};

// HOST_Measurement: 10 uV and 0.1 mA steps.
inline constexpr SignalLayout kMeasVoltage{"Voltage", 24, 20, ValueType::unsigned_int, 1e-5, 0.0, 0.0, 10.48575, "V", Coding::physical};
inline constexpr SignalLayout kMeasCurrent{"Current", 44, 20, ValueType::signed_int, 1e-4, 0.0, -52.4288, 52.4287, "A", Coding::physical};

// HOST_Temperature
inline constexpr SignalLayout kTemperature{"Temperature", 16, 16, ValueType::unsigned_int, 0.01, 0.0, 0.0, 655.35, "K", Coding::physical};

// BMS_Estimate1
inline constexpr SignalLayout kRFilm{"RFilm", 24, 32, ValueType::unsigned_int, 1e-10, 0.0, 0.0, 0.4294967295, "ohm.m2", Coding::physical};
inline constexpr SignalLayout kEstMode{"Mode", 56, 4, ValueType::unsigned_int, 1.0, 0.0, 0.0, 15.0, ""};
inline constexpr SignalLayout kEstRcsiActive{"RcsiActive", 60, 1, ValueType::unsigned_int, 1.0, 0.0, 0.0, 1.0, ""};
inline constexpr SignalLayout kEstValid{"EstimateValid", 61, 1, ValueType::unsigned_int, 1.0, 0.0, 0.0, 1.0, ""};

// BMS_Estimate2 / BMS_Estimate3: theta components as IEEE-754 float32.
inline constexpr SignalLayout kTheta0{"Theta0", 32, 32, ValueType::float32, 1.0, 0.0, 0.0, 0.0, "", Coding::float32};
inline constexpr SignalLayout kTheta1{"Theta1", 32, 32, ValueType::float32, 1.0, 0.0, 0.0, 0.0, "", Coding::float32};

// BMS_Health: lithium loss in 0.1 uAh steps, voltage residual z = y_hat - y in 1 uV steps.
inline constexpr SignalLayout kLiLoss{"LiLoss", 24, 24, ValueType::unsigned_int, 1e-4, 0.0, 0.0, 1677.7215, "mAh", Coding::physical, kMahPerAh};
inline constexpr SignalLayout kZResidual{"ZResidual", 48, 16, ValueType::signed_int, 1.0, 0.0, -32768.0, 32767.0, "uV", Coding::physical, kUvPerV};

// BMS_Uncertainty: the film's 1-sigma in 1e-8 ohm m2 steps, the open-circuit capacity in 1 mAh
// steps and its 1-sigma in 0.1 mAh steps; none (NaN: the paper's RCSI path) as the largest raw value.
inline constexpr SignalLayout kRFilmSd{"RFilmSd", 24, 16, ValueType::unsigned_int, 1e-8, 0.0, 0.0, 0.00065535, "ohm.m2", Coding::physical};
inline constexpr SignalLayout kCapacity{"Capacity", 40, 16, ValueType::unsigned_int, 1.0, 0.0, 0.0, 65535.0, "mAh", Coding::physical, kMahPerAh};
inline constexpr SignalLayout kCapacitySd{"CapacitySd", 56, 8, ValueType::unsigned_int, 0.1, 0.0, 0.0, 25.5, "mAh", Coding::physical, kMahPerAh};

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
                                                   sig::kCtlLockstep, sig::kCtlTickTrigger,
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
inline constexpr SignalLayout kUncertaintySignals[] = {sig::kCrc, sig::kCounter, sig::kSeq, sig::kRFilmSd,
                                                       sig::kCapacity, sig::kCapacitySd};
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
  uncertainty,
  status,
  rx_stats,
};
inline constexpr std::size_t kMessageCount = 10;

namespace id {
inline constexpr std::uint32_t kControl = 0x100;
inline constexpr std::uint32_t kMeasurement = 0x110;
inline constexpr std::uint32_t kTemperature = 0x111;
inline constexpr std::uint32_t kEstimate1 = 0x200;
inline constexpr std::uint32_t kEstimate2 = 0x201;
inline constexpr std::uint32_t kEstimate3 = 0x202;
inline constexpr std::uint32_t kHealth = 0x203;
inline constexpr std::uint32_t kUncertainty = 0x204;
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
    make_layout("BMS_Uncertainty", id::kUncertainty, 8, Node::bms, Node::host, kUncertaintySignals),
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

}  // namespace bms::fw::can
