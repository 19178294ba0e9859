#include "io/candump_log.hpp"

#include <fmt/format.h>
#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <limits>
#include <stdexcept>
#include <string>

#include "io/input_error.hpp"
#include "io/text_file.hpp"

namespace bms {
namespace {

namespace fs = std::filesystem;

std::string log_error(std::string_view text) {
  try {
    (void)parse_candump_log(text, "bus.log");
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

CanLogEntry entry(double t, std::uint32_t id, std::initializer_list<std::uint8_t> bytes) {
  CanLogEntry e;
  e.time_s = t;
  e.interface = "vcan0";
  e.id = id;
  for (std::uint8_t b : bytes) e.data[e.dlc++] = b;
  return e;
}

TEST(CandumpLog, ReadsClassicFrames) {
  const auto entries = parse_candump_log(
      "(1700000000.123456) vcan0 123#DEADBEEF\n"
      "(1700000000.200000) can1 7FF#\n"
      "(0.5) vcan0 110#00.11.22.33.44.55.66.77\r\n"
      "\n"
      "  (12) vcan0 000#abcdef  \n",
      "bus.log");
  ASSERT_EQ(entries.size(), 4u);
  EXPECT_EQ(entries[0], entry(1700000000.123456, 0x123, {0xDE, 0xAD, 0xBE, 0xEF}));
  EXPECT_DOUBLE_EQ(entries[0].time_s, 1700000000.123456);
  EXPECT_EQ(entries[1].interface, "can1");
  EXPECT_EQ(entries[1].id, 0x7FFu);
  EXPECT_EQ(entries[1].dlc, 0u);
  EXPECT_EQ(entries[2], entry(0.5, 0x110, {0x00, 0x11, 0x22, 0x33, 0x44, 0x55, 0x66, 0x77}));
  EXPECT_EQ(entries[3], entry(12.0, 0x000, {0xAB, 0xCD, 0xEF}));
  for (const auto& e : entries) {
    EXPECT_FALSE(e.extended_id);
    EXPECT_FALSE(e.remote);
  }
}

TEST(CandumpLog, FlagsExtendedAndRemoteFrames) {
  const auto entries = parse_candump_log(
      "(1.000000) vcan0 12345678#0102\n"
      "(2.000000) vcan0 123#R\n"
      "(3.000000) vcan0 1FFFFFFF#R8\n"
      "(4.000000) vcan0 00000123#\n",
      "bus.log");
  ASSERT_EQ(entries.size(), 4u);
  EXPECT_TRUE(entries[0].extended_id);
  EXPECT_EQ(entries[0].id, 0x12345678u);
  EXPECT_EQ(entries[0].dlc, 2u);
  EXPECT_FALSE(entries[0].remote);
  EXPECT_TRUE(entries[1].remote);
  EXPECT_FALSE(entries[1].extended_id);
  EXPECT_EQ(entries[1].dlc, 0u);
  EXPECT_TRUE(entries[2].remote);
  EXPECT_TRUE(entries[2].extended_id);
  EXPECT_EQ(entries[2].dlc, 8u);
  EXPECT_EQ(entries[2].data, (std::array<std::uint8_t, 8>{}));
  // An extended frame with a small id is still extended: not the BMS's 11-bit 0x123.
  EXPECT_TRUE(entries[3].extended_id);
  EXPECT_EQ(entries[3].id, 0x123u);
}

TEST(CandumpLog, ErrorsNameTheLineAndTheProblem) {
  EXPECT_EQ(log_error("(1.0) vcan0 123#00\n(2.0) vcan0 123#0\n"),
            "bus.log: line 2: frame '123#0': odd number of hex digits in the data");
  EXPECT_EQ(log_error("\n\n(1.0) vcan0 800#00\n"), "bus.log: line 3: 11-bit identifier 0x800 above 0x7FF");
  EXPECT_EQ(log_error("(1.0) vcan0 12#00"),
            "bus.log: line 1: identifier '12' must have 3 (11-bit) or 8 (29-bit) hex digits");
  EXPECT_EQ(log_error("(1.0) vcan0 1234#00"),
            "bus.log: line 1: identifier '1234' must have 3 (11-bit) or 8 (29-bit) hex digits");
  EXPECT_EQ(log_error("(1.0) vcan0 12G#00"), "bus.log: line 1: identifier '12G' is not hexadecimal");
  EXPECT_EQ(log_error("(1.0) vcan0 40000000#00"),
            "bus.log: line 1: 29-bit identifier 0x40000000 above 0x1FFFFFFF");
  EXPECT_EQ(log_error("(1.0) vcan0 20000080#0000000000000000"),
            "bus.log: line 1: error frame (identifier 0x20000080 has CAN_ERR_FLAG): not supported");
  EXPECT_EQ(log_error("(1.0) vcan0 123##1DEADBEEF"),
            "bus.log: line 1: CAN FD frame '123##1DEADBEEF': not supported (classic CAN only)");
  EXPECT_EQ(log_error("(1.0) vcan0 123#001122334455667788"),
            "bus.log: line 1: frame '123#001122334455667788': more than 8 data bytes (classic CAN only)");
  EXPECT_EQ(log_error("(1.0) vcan0 123#0011223344556677_D"),
            "bus.log: line 1: frame '123#0011223344556677_D': a DLC above 8 ('_' suffix) is not supported");
  EXPECT_EQ(log_error("(1.0) vcan0 123#R9"),
            "bus.log: line 1: remote frame '123#R9': the length after 'R' must be one digit 0..8");
  EXPECT_EQ(log_error("(1.0) vcan0 123#DEADBEEG"), "bus.log: line 1: frame '123#DEADBEEG': data is not hexadecimal");
  EXPECT_EQ(log_error("(1.0) vcan0 123#00."), "bus.log: line 1: frame '123#00.' ends with '.'");
  EXPECT_EQ(log_error("(1.0) vcan0 123DEAD"), "bus.log: line 1: frame '123DEAD' has no '#' (expected ID#DATA)");
  EXPECT_EQ(log_error("(1.0) vcan0 123#00 R"), "bus.log: line 1: unexpected text after the frame: 'R'");
  EXPECT_EQ(log_error("(1.0) 123#00"),
            "bus.log: line 1: expected '(TIME) INTERFACE FRAME', e.g. '(1700000000.123456) vcan0 123#DEADBEEF'");
  EXPECT_EQ(log_error("1.0 vcan0 123#00"),
            "bus.log: line 1: bad timestamp '1.0' (expected '(SECONDS.FRACTION)')");
  for (const char* t : {"(-1.0)", "(1.)", "(.5)", "(1.5.2)", "(1e5)", "(1234567890123.0)", "(1.1234567890)", "()"}) {
    EXPECT_NE(log_error(std::string(t) + " vcan0 123#00").find("bad timestamp"), std::string::npos) << t;
  }
  EXPECT_EQ(log_error("(1.0) a_very_long_interface 123#00"),
            "bus.log: line 1: interface name 'a_very_long_interface' longer than 15 characters");
  EXPECT_EQ(log_error(std::string("(1.0) vc\x01n0 123#00")),
            "bus.log: line 1: interface name 'vc\\x01n0' holds a non-printable byte");
}

TEST(CandumpLog, WritesWhatItReadsAndRejectsUnwritableEntries) {
  const std::string text =
      "(1700000000.123456) vcan0 123#DEADBEEF\n"
      "(0.000001) can0 7FF#\n"
      "(5.000000) vcan0 12345678#0102030405060708\n"
      "(6.000000) vcan0 110#R\n"
      "(7.000000) vcan0 00000110#R3\n";
  std::string back;
  for (const CanLogEntry& e : parse_candump_log(text, "bus.log")) back += format_candump_line(e) + "\n";
  EXPECT_EQ(back, text);
  // Sub-microsecond times round to the microsecond, never to "x.1000000".
  EXPECT_EQ(format_candump_line(entry(1.9999996, 0x100, {})), "(2.000000) vcan0 100#");
  EXPECT_EQ(format_candump_line(entry(3.0000004, 0x100, {1})), "(3.000000) vcan0 100#01");

  CanLogEntry bad = entry(1.0, 0x100, {});
  bad.dlc = 9;
  EXPECT_THROW(format_candump_line(bad), std::invalid_argument);
  bad = entry(1.0, 0x800, {});
  EXPECT_THROW(format_candump_line(bad), std::invalid_argument);
  bad.extended_id = true;
  EXPECT_NO_THROW(format_candump_line(bad));
  bad = entry(-1.0, 0x100, {});
  EXPECT_THROW(format_candump_line(bad), std::invalid_argument);
  bad = entry(std::numeric_limits<double>::quiet_NaN(), 0x100, {});
  EXPECT_THROW(format_candump_line(bad), std::invalid_argument);
  bad = entry(1.0, 0x100, {});
  bad.interface = "vcan 0";
  EXPECT_THROW(format_candump_line(bad), std::invalid_argument);
  bad.interface = "";
  EXPECT_THROW(format_candump_line(bad), std::invalid_argument);
}

TEST(CandumpLog, WriterCommitsAtomicallyAndFileReadsBack) {
  const fs::path dir = fs::temp_directory_path() / fmt::format("bms_candump_test_{}", ::getpid());
  fs::remove_all(dir);
  fs::create_directories(dir);
  const fs::path file = dir / "bus.log";
  {
    CandumpWriter w(file);
    w.write(entry(1.5, 0x110, {1, 2, 3}));
    EXPECT_FALSE(fs::exists(file));
    EXPECT_TRUE(fs::exists(dir / "bus.log.tmp"));
  }
  EXPECT_FALSE(fs::exists(file)) << "no commit: nothing that looks complete";
  EXPECT_FALSE(fs::exists(dir / "bus.log.tmp"));
  {
    CandumpWriter w(file);
    for (int i = 0; i < 3; ++i) w.write(entry(1.0 + i, 0x200 + static_cast<std::uint32_t>(i), {0xAA}));
    EXPECT_THROW(w.write(entry(1.0, 0x900, {})), std::invalid_argument);
    EXPECT_EQ(w.lines(), 3u);
    w.commit();
  }
  const auto entries = read_candump_log(file);
  ASSERT_EQ(entries.size(), 3u);
  EXPECT_EQ(entries[2], entry(3.0, 0x202, {0xAA}));
  EXPECT_THROW(read_candump_log(dir / "missing.log"), InputError);
  fs::remove_all(dir);
}

}  // namespace
}  // namespace bms
