// The BMS CAN protocol's codec: Intel bit packing, scaling, and encode/decode of every
// message by walking its row of the signal table (can_signal_table.hpp) together with the
// message's member binding (can_messages.hpp). No message has code of its own here.
//
// - Coding::physical rounds to the nearest step and saturates at the signal's raw range;
//   NaN encodes as the end of the range a receiver rejects (see to_raw).
// - Coding::integer writes the member's low `length` bits (Seq is the tick mod 4096).
// - Coding::float32 copies the IEEE-754 bits.
//
// Header-only C++17: no heap, no exceptions, no RTTI; usable on a Cortex-M.
#pragma once

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <type_traits>

#include "bms/fw/can/can_crc.hpp"
#include "bms/fw/can/can_messages.hpp"
#include "bms/fw/can/can_sequence.hpp"
#include "bms/fw/can/can_signal_table.hpp"

namespace bms::fw::can {

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
  if (len == 0u || len >= 64u) return static_cast<std::int64_t>(raw);  // no sign bit to extend
  const std::uint64_t sign = std::uint64_t{1} << (len - 1u);
  const std::uint64_t value = raw & ((sign << 1u) - 1u);
  return (value & sign) != 0u ? static_cast<std::int64_t>(value) - static_cast<std::int64_t>(sign << 1u)
                              : static_cast<std::int64_t>(value);
}

/// Smallest and largest raw integer of a signal (as signed values).
constexpr std::int64_t raw_min(const SignalLayout& s) {
  // The analyzer assumes a signal of length 0 (shift by -1): every SignalLayout in can_signal_table.hpp
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

/// For a signal whose largest raw value means "none" (NaN): a real SI value at or beyond the top
/// of the range becomes the value one step under it, so that it never reads as none.
inline double below_none(double si, const SignalLayout& s) {
  const double top_si = (s.max - s.factor) / s.units_per_si;
  return si > top_si ? top_si : si;
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
// One signal of the table <-> one member's value. Every member type converts to double
// without loss (integers up to 32 bits, float), so one path serves all codings.

/// Write a member's SI value into its signal.
inline void put_signal(std::uint8_t* data, const SignalLayout& s, double value_si) {
  switch (s.coding) {
    case Coding::integer: put_uint(data, s, static_cast<std::uint64_t>(value_si)); break;
    case Coding::physical: put_physical(data, s, value_si * s.units_per_si); break;
    case Coding::float32: put_float32(data, s, static_cast<float>(value_si)); break;
  }
}

/// Read a signal as the member's SI value.
inline double get_signal(const std::uint8_t* data, const SignalLayout& s) {
  switch (s.coding) {
    case Coding::integer: return static_cast<double>(get_uint(data, s));
    case Coding::physical: return get_physical(data, s) / s.units_per_si;
    case Coding::float32: return static_cast<double>(get_float32(data, s));
  }
  return 0.0;
}

constexpr double member_value(bool v) { return v ? 1.0 : 0.0; }
constexpr double member_value(Mode v) { return static_cast<double>(static_cast<std::uint8_t>(v)); }
template <class T>
constexpr double member_value(T v) {
  return static_cast<double>(v);
}

inline void assign_member(bool& m, double v) { m = v != 0.0; }
inline void assign_member(Mode& m, double v) { m = mode_from_raw(static_cast<std::uint64_t>(v)); }
inline void assign_member(double& m, double v) { m = v; }
template <class T>
void assign_member(T& m, double v) {
  m = static_cast<T>(v);
}

/// Signals of a message before its bound members: Crc, Counter.
inline constexpr std::size_t kFramingSignals = 2;

/// Number of members a message's binding lists (must equal its payload signals).
template <class M>
std::size_t bound_member_count() {
  M m{};
  std::size_t n = 0;
  MessageTraits<M>::fields(m, [&n](const auto&) { ++n; });
  return n;
}

/// Write every payload signal of `m` (not Crc and Counter) into a zeroed payload.
template <class M>
void pack(const M& m, std::uint8_t* data) {
  const SignalLayout* s = layout(MessageTraits<M>::kMsg).signals + kFramingSignals;
  MessageTraits<M>::fields(m, [&s, data](const auto& member) {
    // A float member is copied, not widened: widening would quiet a signalling NaN's bits.
    if constexpr (std::is_same_v<std::decay_t<decltype(member)>, float>)
      put_float32(data, *s++, member);
    else
      put_signal(data, *s++, member_value(member));
  });
}

/// Read every payload signal of `data` into `m`.
template <class M>
void unpack(const std::uint8_t* data, M& m) {
  const SignalLayout* s = layout(MessageTraits<M>::kMsg).signals + kFramingSignals;
  MessageTraits<M>::fields(m, [&s, data](auto& member) {
    if constexpr (std::is_same_v<std::decay_t<decltype(member)>, float>)
      member = get_float32(data, *s++);
    else
      assign_member(member, get_signal(data, *s++));
  });
}

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
  can::pack(m, frame.data);
  put_uint(frame.data, sig::kCounter, counter & kCounterMask);
  frame.data[0] = frame_crc(frame.id, frame.data, frame.len);
}

/// Decode the signals of `frame` into `m` when id and length match M; no CRC or
/// counter check (use Receiver for that). Returns false on a mismatch.
template <class M, class FrameT>
bool decode(const FrameT& frame, M& m) {
  const MessageLayout& l = layout(MessageTraits<M>::kMsg);
  if (frame.id != l.id || frame.len != l.dlc) return false;
  can::unpack(frame.data, m);
  return true;
}

constexpr std::uint8_t frame_counter(const std::uint8_t* data) {
  return static_cast<std::uint8_t>(get_bits(data, sig::kCounter.start_bit, sig::kCounter.length));
}

template <class FrameT>
constexpr bool frame_crc_ok(const FrameT& frame) {
  return frame.len >= 1u && frame.data[0] == frame_crc(frame.id, frame.data, frame.len);
}

}  // namespace bms::fw::can
