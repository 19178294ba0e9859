#pragma once
// candump log files (can-utils `candump -l` / `-L`), one frame per line:
//   (1700000000.123456) vcan0 123#DEADBEEF
// time in seconds, interface name, identifier in hex (3 digits: 11-bit standard frame,
// 8 digits: 29-bit extended frame), '#', 0..8 data bytes in hex ('.' between bytes is
// accepted, as cansend does). A remote frame is `123#R` or `123#R<len>`.
// Extended and remote frames are read and flagged (extended_id, remote), never confused
// with the 11-bit data frames the BMS protocol uses; CAN FD (`123##...`), error frames
// (CAN_ERR_FLAG in the id) and CAN XL are rejected. Used by the host-in-the-loop to
// record and replay bus traffic.
#include <array>
#include <cstdint>
#include <cstdio>
#include <filesystem>

#include "io/atomic_file.hpp"
#include <string>
#include <string_view>
#include <vector>

namespace bms {

struct CanLogEntry {
  double time_s = 0.0;          // candump's timestamp (wall clock or since start), >= 0
  std::string interface;        // e.g. "vcan0"
  std::uint32_t id = 0;         // 11-bit, or 29-bit when extended_id; no flag bits
  std::uint8_t dlc = 0;         // 0..8 (for a remote frame: the requested length)
  std::array<std::uint8_t, 8> data{};  // bytes from dlc on are 0 (all 0 for a remote frame)
  bool extended_id = false;     // 29-bit identifier (8 hex digits in the log)
  bool remote = false;          // remote transmission request: no data

  bool operator==(const CanLogEntry& o) const {
    return time_s == o.time_s && interface == o.interface && id == o.id && dlc == o.dlc &&
           data == o.data && extended_id == o.extended_id && remote == o.remote;
  }
  bool operator!=(const CanLogEntry& o) const { return !(*this == o); }
};

// Limits of what is read: the Linux interface-name limit (IFNAMSIZ - 1) and a timestamp of
// at most 12 integer digits (year 33658 in Unix seconds) with 1..9 fraction digits.
inline constexpr std::size_t kCanLogMaxInterface = 15;

// One line, without its line end. Throws InputError "NAME: line N: PROBLEM".
CanLogEntry parse_candump_line(std::string_view line, std::string_view name, std::size_t line_number);

// Every line of a log. Blank lines are skipped; CRLF line ends are accepted; anything else
// that is not a frame is an InputError naming the line.
std::vector<CanLogEntry> parse_candump_log(std::string_view text, std::string_view name);
std::vector<CanLogEntry> read_candump_log(const std::filesystem::path& file);

// The line for one entry, as candump -l writes it (no line end): 6 fraction digits,
// upper-case hex. Throws std::invalid_argument for an entry no log could hold (dlc > 8,
// id out of range, negative or non-finite time, empty interface or one with spaces).
// Reading the line back gives the entry again, with the time rounded to the microsecond.
std::string format_candump_line(const CanLogEntry& entry);

// Writes FILE.tmp and renames it to FILE in commit() (the project's rule: a complete-looking
// file is a complete file); without commit() the destructor deletes FILE.tmp. Lines are
// buffered and flushed in blocks, so a long recording costs one write per block.
class CandumpWriter {
 public:
  explicit CandumpWriter(std::filesystem::path file);
  CandumpWriter(const CandumpWriter&) = delete;
  CandumpWriter& operator=(const CandumpWriter&) = delete;

  void write(const CanLogEntry& entry);
  void commit();
  std::size_t lines() const { return lines_; }
  const std::filesystem::path& path() const { return out_.path(); }

 private:
  AtomicFileWriter out_;
  std::size_t lines_ = 0;
};

}  // namespace bms
