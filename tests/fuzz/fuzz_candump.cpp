// Fuzz target: the candump log reader and writer (host_sim/src/io/candump_log.*).
// Input: the log text. Bad lines must end in InputError naming the line; every accepted
// entry must be writable, and writing then reading it back must give the same entry (the
// time rounded to the microsecond: written once more, it gives the same line).
#include <cstdint>
#include <cstdlib>
#include <string>
#include <string_view>

#include "io/candump_log.hpp"
#include "io/input_error.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const std::string_view text(reinterpret_cast<const char*>(data), size);
  std::vector<bms::CanLogEntry> entries;
  try {
    entries = bms::parse_candump_log(text, "fuzz.log");
  } catch (const bms::InputError& e) {
    if (std::string_view(e.what()).substr(0, 15) != "fuzz.log: line ") std::abort();
    return 0;
  }
  for (const bms::CanLogEntry& e : entries) {
    if (e.dlc > 8 || e.interface.empty() || !(e.time_s >= 0.0)) std::abort();
    for (std::size_t i = e.remote ? 0 : e.dlc; i < 8; ++i) {
      if (e.data[i] != 0) std::abort();
    }
    const std::string line = bms::format_candump_line(e);  // must not throw
    const bms::CanLogEntry back = bms::parse_candump_line(line, "again", 1);
    if (back.interface != e.interface || back.id != e.id || back.dlc != e.dlc || back.data != e.data ||
        back.extended_id != e.extended_id || back.remote != e.remote) {
      std::abort();
    }
    if (bms::format_candump_line(back) != line) std::abort();
  }
  return 0;
}
