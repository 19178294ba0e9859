// CRC-8 used on every frame of the BMS CAN protocol: CRC-8/SAE-J1850, the CRC-8 of
// AUTOSAR's Crc_CalculateCRC8: polynomial 0x1D, initial value 0xFF, no reflection,
// final XOR 0xFF. Catalogue check value: CRC of the ASCII string "123456789" = 0x4B.
//
// A frame's CRC covers the 11-bit identifier as two bytes, low byte first
// (id & 0xFF, id >> 8), then the payload bytes 1..len-1: byte 0 holds the CRC itself.
// Covering the identifier catches a frame whose id was corrupted into another valid id.
// Header-only, constexpr, no heap: usable on Cortex-M.
#pragma once

#include <cstddef>
#include <cstdint>

namespace bms::fw::can {

inline constexpr std::uint8_t kCrc8Poly = 0x1D;
inline constexpr std::uint8_t kCrc8Init = 0xFF;
inline constexpr std::uint8_t kCrc8XorOut = 0xFF;

namespace detail {
struct Crc8Table {
  std::uint8_t v[256];
};
constexpr Crc8Table make_crc8_table() {
  Crc8Table t{};
  for (unsigned i = 0; i < 256u; ++i) {
    unsigned c = i;
    for (int b = 0; b < 8; ++b) c = ((c & 0x80u) != 0u) ? ((c << 1u) ^ kCrc8Poly) : (c << 1u);
    t.v[i] = static_cast<std::uint8_t>(c & 0xFFu);
  }
  return t;
}
inline constexpr Crc8Table kCrc8Table = make_crc8_table();
}  // namespace detail

/// Feed one byte into a running (not yet final-XORed) CRC register.
constexpr std::uint8_t crc8_update(std::uint8_t reg, std::uint8_t byte) {
  return detail::kCrc8Table.v[static_cast<std::uint8_t>(reg ^ byte)];
}

/// CRC-8/SAE-J1850 of a byte string.
constexpr std::uint8_t crc8_sae_j1850(const std::uint8_t* data, std::size_t len) {
  std::uint8_t reg = kCrc8Init;
  for (std::size_t i = 0; i < len; ++i) reg = crc8_update(reg, data[i]);
  return static_cast<std::uint8_t>(reg ^ kCrc8XorOut);
}

/// The CRC carried in byte 0 of every protocol frame (see the file comment).
constexpr std::uint8_t frame_crc(std::uint32_t id, const std::uint8_t* data, std::uint8_t len) {
  std::uint8_t reg = kCrc8Init;
  reg = crc8_update(reg, static_cast<std::uint8_t>(id & 0xFFu));
  reg = crc8_update(reg, static_cast<std::uint8_t>((id >> 8u) & 0x07u));
  for (std::uint8_t i = 1; i < len; ++i) reg = crc8_update(reg, data[i]);
  return static_cast<std::uint8_t>(reg ^ kCrc8XorOut);
}

}  // namespace bms::fw::can
