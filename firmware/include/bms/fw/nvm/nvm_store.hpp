#pragma once
// Two-slot record store for non-volatile memory: keeps the last committed copy of one
// trivially copyable payload (the estimator's State) through power loss at any instant.
//
// Why two slots: a write interrupted by power loss leaves its slot half old, half updated (a
// "torn" record). Writing always goes to the slot that does NOT hold the newest valid
// record, so the newest committed record is never touched; at start-up the valid record
// with the highest sequence number wins. A torn record fails its CRC and is never accepted.
//
// Record layout (all integers little-endian, independent of the CPU's byte order):
//   offset  size  field
//        0     4  magic            kRecordMagic ("BMSN")
//        4     2  format version   kRecordFormatVersion (this layout)
//        6     2  reserved         0
//        8     4  layout tag       the payload type's tag, a schema hash (state_schema.hpp):
//                                  a record of another payload type or version is refused
//       12     4  sequence number  +1 per commit, modulo 2^32 (wraparound-safe comparison)
//       16     4  payload length   bytes
//       20     n  payload          the payload's object representation (memcpy)
//     20+n     4  CRC-32           IEEE 802.3 over bytes [0, 20+n)
// The payload is copied byte for byte: a record is read back by the same firmware image
// on the same CPU; the layout tag names the payload's fields, types and order.
//
// Slots: slot i occupies [base + i*stride, base + i*stride + record length), stride = the
// record length rounded up to whole pages, so each slot is erased on its own (flash needs
// an erase before a write; erasing also makes a torn record's tail read as erased bytes).
// A commit is: erase the slot, write the whole record in one write(), read it back and
// check it. The CRC is the commit mark: until its last byte has landed, the record is invalid.
//
// Nvm: any class with the member functions of bms::hal::NonVolatileMemory (size_bytes,
// page_size, read, write, erase), including that interface itself. The firmware core does
// not depend on the HAL, so the store only assumes that a value-initialised status means
// success (bms::hal::Status::ok == 0; tests/hal checks this).
//
// Header-only C++17: no heap, no exceptions, no RTTI; usable on a Cortex-M.
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <type_traits>
#include <utility>

namespace bms::fw::nvm {

// ---------------------------------------------------------------------------------------
// CRC-32 (IEEE 802.3, as zlib): reflected polynomial 0xEDB88320, initial value 0xFFFFFFFF,
// final XOR 0xFFFFFFFF. Catalogue check value: CRC of the ASCII string "123456789" = 0xCBF43926.
// 32 bits (not the CAN frames' CRC-8): a record is a few hundred bytes and is trusted for
// the whole life of the device; any error of up to 3 bits in it is detected for certain.

namespace detail {
struct Crc32Table {
  std::uint32_t v[256];
};
constexpr Crc32Table make_crc32_table() {
  Crc32Table t{};
  for (std::uint32_t i = 0; i < 256u; ++i) {
    std::uint32_t c = i;
    for (int b = 0; b < 8; ++b) c = ((c & 1u) != 0u) ? ((c >> 1u) ^ 0xEDB88320u) : (c >> 1u);
    t.v[i] = c;
  }
  return t;
}
inline constexpr Crc32Table kCrc32Table = make_crc32_table();
}  // namespace detail

inline constexpr std::uint32_t kCrc32Init = 0xFFFFFFFFu;

/// Feed bytes into a running (not yet final-XORed) CRC-32 register.
constexpr std::uint32_t crc32_update(std::uint32_t reg, const std::uint8_t* data, std::size_t len) {
  for (std::size_t i = 0; i < len; ++i) {
    reg = detail::kCrc32Table.v[(reg ^ data[i]) & 0xFFu] ^ (reg >> 8u);
  }
  return reg;
}

/// CRC-32 of a byte string.
constexpr std::uint32_t crc32(const std::uint8_t* data, std::size_t len) {
  return crc32_update(kCrc32Init, data, len) ^ 0xFFFFFFFFu;
}

// ---------------------------------------------------------------------------------------
// Record encoding and decoding (no NVM involved: also what the fuzzer drives)

inline constexpr std::uint32_t kRecordMagic = 0x4E534D42u;  // bytes 'B' 'M' 'S' 'N'
inline constexpr std::uint16_t kRecordFormatVersion = 1u;
inline constexpr std::size_t kRecordHeaderBytes = 20;
inline constexpr std::size_t kRecordCrcBytes = 4;
inline constexpr std::size_t kRecordOverheadBytes = kRecordHeaderBytes + kRecordCrcBytes;
inline constexpr std::uint8_t kErasedByte = 0xFF;  // bms::hal::kNvmErasedByte

constexpr std::size_t record_bytes(std::size_t payload_bytes) { return kRecordOverheadBytes + payload_bytes; }

/// What a slot holds. Only `valid` is ever accepted.
enum class RecordCheck : std::uint8_t {
  valid,
  erased,       ///< every byte reads as erased: nothing was ever written (or an erase landed)
  truncated,    ///< fewer bytes than a record with an empty payload
  bad_magic,    ///< not a record (or torn within its first 4 bytes)
  bad_length,   ///< the payload length does not fit in the slot, or is not the expected one
  bad_crc,      ///< torn or corrupted
  bad_version,  ///< a record of another format version (CRC good)
  bad_layout,   ///< a record of another payload type or version (CRC good)
  unknown,      ///< not read yet, or a write to it failed (contents unknown)
};

constexpr const char* record_check_name(RecordCheck c) {
  switch (c) {
    case RecordCheck::valid: return "valid";
    case RecordCheck::erased: return "erased";
    case RecordCheck::truncated: return "truncated";
    case RecordCheck::bad_magic: return "bad_magic";
    case RecordCheck::bad_length: return "bad_length";
    case RecordCheck::bad_crc: return "bad_crc";
    case RecordCheck::bad_version: return "bad_version";
    case RecordCheck::bad_layout: return "bad_layout";
    case RecordCheck::unknown: return "unknown";
  }
  return "unknown";
}

namespace detail {
constexpr void put_u16(std::uint8_t* p, std::uint16_t v) {
  p[0] = static_cast<std::uint8_t>(v & 0xFFu);
  p[1] = static_cast<std::uint8_t>((v >> 8u) & 0xFFu);
}
constexpr void put_u32(std::uint8_t* p, std::uint32_t v) {
  for (unsigned i = 0; i < 4u; ++i) p[i] = static_cast<std::uint8_t>((v >> (8u * i)) & 0xFFu);
}
constexpr std::uint16_t get_u16(const std::uint8_t* p) {
  return static_cast<std::uint16_t>(p[0] | (p[1] << 8u));
}
constexpr std::uint32_t get_u32(const std::uint8_t* p) {
  return static_cast<std::uint32_t>(p[0]) | (static_cast<std::uint32_t>(p[1]) << 8u) |
         (static_cast<std::uint32_t>(p[2]) << 16u) | (static_cast<std::uint32_t>(p[3]) << 24u);
}
}  // namespace detail

/// True when sequence `a` was committed after `b`: a is 1..2^31-1 steps ahead of b modulo
/// 2^32, so counting through 0xFFFFFFFF -> 0 keeps the order. (Two slots hold sequences
/// one apart; a distance of 2^31 or 0 only arises from foreign data: neither is newer.)
constexpr bool sequence_newer(std::uint32_t a, std::uint32_t b) {
  const std::uint32_t ahead = a - b;  // unsigned: wraps by definition
  return ahead != 0u && ahead < 0x80000000u;
}

/// Write a record into `out` (capacity `out_len`). Returns the record length, or 0 when it
/// does not fit (nothing written then).
inline std::size_t encode_record(const void* payload, std::size_t payload_bytes, std::uint32_t layout_tag,
                                 std::uint32_t sequence, std::uint8_t* out, std::size_t out_len) {
  if (payload_bytes > 0xFFFFFFFFu - kRecordOverheadBytes || out_len < record_bytes(payload_bytes)) return 0;
  detail::put_u32(out + 0, kRecordMagic);
  detail::put_u16(out + 4, kRecordFormatVersion);
  detail::put_u16(out + 6, 0u);
  detail::put_u32(out + 8, layout_tag);
  detail::put_u32(out + 12, sequence);
  detail::put_u32(out + 16, static_cast<std::uint32_t>(payload_bytes));
  if (payload_bytes > 0u) std::memcpy(out + kRecordHeaderBytes, payload, payload_bytes);
  const std::size_t crc_at = kRecordHeaderBytes + payload_bytes;
  detail::put_u32(out + crc_at, crc32(out, crc_at));
  return crc_at + kRecordCrcBytes;
}

/// A decoded record; `payload` points into the decoded bytes.
struct RecordView {
  std::uint32_t layout_tag = 0;
  std::uint32_t sequence = 0;
  const std::uint8_t* payload = nullptr;
  std::size_t payload_bytes = 0;
};

/// Check the record at the start of `bytes` (`len` bytes available; bytes after the record
/// are ignored). `layout_tag` and `payload_bytes` are what the caller expects. `out` is
/// filled only for `valid`. Never reads outside [bytes, bytes + len).
inline RecordCheck check_record(const std::uint8_t* bytes, std::size_t len, std::uint32_t layout_tag,
                                std::size_t payload_bytes, RecordView& out) {
  if (len < kRecordOverheadBytes) return RecordCheck::truncated;
  // Erased: only the span a record of the expected length would occupy, so an erased slot
  // followed by other data still reads as "erased", not as "bad_magic".
  const std::size_t span = record_bytes(payload_bytes) < len ? record_bytes(payload_bytes) : len;
  bool erased = true;
  for (std::size_t i = 0; erased && i < span; ++i) erased = bytes[i] == kErasedByte;
  if (erased) return RecordCheck::erased;
  if (detail::get_u32(bytes) != kRecordMagic) return RecordCheck::bad_magic;
  const std::uint32_t stored_len = detail::get_u32(bytes + 16);
  if (stored_len > len - kRecordOverheadBytes) return RecordCheck::bad_length;
  const std::size_t crc_at = kRecordHeaderBytes + stored_len;
  if (detail::get_u32(bytes + crc_at) != crc32(bytes, crc_at)) return RecordCheck::bad_crc;
  // The CRC holds: what follows tells a foreign record from ours.
  if (detail::get_u16(bytes + 4) != kRecordFormatVersion || detail::get_u16(bytes + 6) != 0u)
    return RecordCheck::bad_version;
  if (detail::get_u32(bytes + 8) != layout_tag) return RecordCheck::bad_layout;
  if (stored_len != payload_bytes) return RecordCheck::bad_length;
  out.layout_tag = layout_tag;
  out.sequence = detail::get_u32(bytes + 12);
  out.payload = bytes + kRecordHeaderBytes;
  out.payload_bytes = stored_len;
  return RecordCheck::valid;
}

// ---------------------------------------------------------------------------------------
// The store

enum class StoreStatus : std::uint8_t {
  ok,
  empty,           ///< load: both slots erased (a fresh device): nothing to restore, not a fault
  no_valid_record, ///< load: something is stored, but no slot holds a valid record (a fault)
  io_error,        ///< the NVM failed (read, erase, write, or the read-back check); for save:
                   ///< the record was not committed, the previous one is still the newest
  invalid_config,  ///< base offset not page-aligned, slots outside the device, page size 0
};

constexpr const char* store_status_name(StoreStatus s) {
  switch (s) {
    case StoreStatus::ok: return "ok";
    case StoreStatus::empty: return "empty";
    case StoreStatus::no_valid_record: return "no_valid_record";
    case StoreStatus::io_error: return "io_error";
    case StoreStatus::invalid_config: return "invalid_config";
  }
  return "unknown";
}

inline constexpr int kSlotCount = 2;

/// Keeps the last committed Payload in two slots of `nvm` starting at `base_offset`.
/// LayoutTag identifies the payload type and version (RcsiEstimator<...>::kLayoutTag).
template <class Payload, std::uint32_t LayoutTag, class Nvm>
class RecordStore {
  static_assert(std::is_trivially_copyable<Payload>::value, "the payload is stored as bytes");

 public:
  static constexpr std::size_t kPayloadBytes = sizeof(Payload);
  static constexpr std::size_t kRecordBytes = record_bytes(kPayloadBytes);

  RecordStore(Nvm& nvm, std::size_t base_offset) : nvm_(nvm), base_(base_offset) {
    const std::size_t page = nvm_.page_size();
    if (page == 0u) return;
    stride_ = (kRecordBytes + page - 1u) / page * page;
    const std::size_t size = nvm_.size_bytes();
    config_ok_ = base_ % page == 0u && base_ <= size && stride_ <= (size - base_) / kSlotCount;
  }

  /// Bytes of NVM the store uses from base_offset on (both slots, whole pages).
  std::size_t footprint_bytes() const { return kSlotCount * stride_; }
  std::size_t slot_offset(int slot) const { return base_ + static_cast<std::size_t>(slot) * stride_; }
  bool config_ok() const { return config_ok_; }

  /// Read both slots and copy the newest valid payload into `out` (unchanged unless ok).
  StoreStatus load(Payload& out) {
    fell_back_ = false;
    const StoreStatus s = scan();
    if (s != StoreStatus::ok) return s;
    // The winning slot was validated by scan(); read it again so that no second buffer
    // holds both slots at once (RAM is scarce on the target).
    RecordView view;
    if (!read_slot(newest_slot_) ||
        check_record(buf_, kRecordBytes, LayoutTag, kPayloadBytes, view) != RecordCheck::valid ||
        view.sequence != newest_seq_) {
      scanned_ = false;
      return StoreStatus::io_error;
    }
    std::memcpy(&out, view.payload, kPayloadBytes);
    const RecordCheck other = check_[1 - newest_slot_];
    fell_back_ = other != RecordCheck::valid && other != RecordCheck::erased;
    return StoreStatus::ok;
  }

  /// After a successful load(): the other slot held something unreadable (a torn or corrupt
  /// record, or a foreign one), so the record loaded may be older than the last commit
  /// attempted: a rollback the application must report.
  bool fell_back() const { return fell_back_; }

  /// Commit `payload` to the slot not holding the newest valid record. ok: the record is
  /// durable and verified; otherwise the previously committed record is still the newest.
  StoreStatus save(const Payload& payload) {
    if (!config_ok_) return StoreStatus::invalid_config;
    if (!scanned_) {
      // Never write before knowing which slot holds the newest record.
      const StoreStatus s = scan();
      if (s == StoreStatus::io_error || s == StoreStatus::invalid_config) return s;
    }
    const int target = has_newest_ ? 1 - newest_slot_ : 0;
    const std::uint32_t seq = has_newest_ ? newest_seq_ + 1u : 1u;  // wraps by design
    check_[target] = RecordCheck::unknown;  // whatever happens next, its old content is gone
    const std::size_t at = slot_offset(target);
    if (!ok(nvm_.erase(at, stride_))) return StoreStatus::io_error;
    if (encode_record(&payload, kPayloadBytes, LayoutTag, seq, buf_, sizeof buf_) != kRecordBytes)
      return StoreStatus::invalid_config;
    if (!ok(nvm_.write(at, buf_, kRecordBytes))) return StoreStatus::io_error;
    // Read back: a write that reported success but did not stick must not count as a commit.
    // The payload is compared as bytes on purpose: what must match is exactly what was
    // copied out of `payload` (padding and NaN bits included), not its value.
    RecordView view;
    if (!read_slot(target) ||
        check_record(buf_, kRecordBytes, LayoutTag, kPayloadBytes, view) != RecordCheck::valid ||
        view.sequence != seq ||
        std::memcmp(view.payload, &payload, kPayloadBytes) != 0) {  // NOLINT(bugprone-suspicious-memory-comparison,cert-exp42-c,cert-flp37-c)
      return StoreStatus::io_error;
    }
    check_[target] = RecordCheck::valid;
    seq_[target] = seq;
    has_newest_ = true;
    newest_slot_ = target;
    newest_seq_ = seq;
    return StoreStatus::ok;
  }

  /// Diagnostics of the last load()/save(): what each slot holds, and its sequence number
  /// (meaningful for valid slots only).
  RecordCheck slot_check(int slot) const { return check_[slot]; }
  std::uint32_t slot_sequence(int slot) const { return seq_[slot]; }
  /// Slot and sequence of the newest committed record; has_record() false if none.
  bool has_record() const { return has_newest_; }
  int newest_slot() const { return newest_slot_; }
  std::uint32_t newest_sequence() const { return newest_seq_; }

 private:
  using NvmStatus = decltype(std::declval<Nvm&>().read(std::size_t{}, static_cast<void*>(nullptr), std::size_t{}));
  static constexpr bool ok(NvmStatus s) { return s == NvmStatus{}; }

  bool read_slot(int slot) { return ok(nvm_.read(slot_offset(slot), buf_, kRecordBytes)); }

  StoreStatus scan() {
    scanned_ = false;
    has_newest_ = false;
    if (!config_ok_) return StoreStatus::invalid_config;
    bool all_erased = true;
    for (int slot = 0; slot < kSlotCount; ++slot) {
      check_[slot] = RecordCheck::unknown;
      if (!read_slot(slot)) return StoreStatus::io_error;
      RecordView view;
      check_[slot] = check_record(buf_, kRecordBytes, LayoutTag, kPayloadBytes, view);
      all_erased = all_erased && check_[slot] == RecordCheck::erased;
      if (check_[slot] != RecordCheck::valid) continue;
      seq_[slot] = view.sequence;
      // Ties (only from foreign data) keep the lower slot: deterministic.
      if (!has_newest_ || sequence_newer(view.sequence, newest_seq_)) {
        has_newest_ = true;
        newest_slot_ = slot;
        newest_seq_ = view.sequence;
      }
    }
    scanned_ = true;
    if (has_newest_) return StoreStatus::ok;
    return all_erased ? StoreStatus::empty : StoreStatus::no_valid_record;
  }

  Nvm& nvm_;
  std::size_t base_;
  std::size_t stride_ = 0;
  bool config_ok_ = false;
  bool scanned_ = false;
  bool fell_back_ = false;
  bool has_newest_ = false;
  int newest_slot_ = 0;
  std::uint32_t newest_seq_ = 0;
  RecordCheck check_[kSlotCount] = {RecordCheck::unknown, RecordCheck::unknown};
  std::uint32_t seq_[kSlotCount] = {0u, 0u};
  // One record's worth of RAM, owned by the store (not the stack): the encode and
  // read-back buffer.
  std::uint8_t buf_[kRecordBytes] = {};
};

}  // namespace bms::fw::nvm
