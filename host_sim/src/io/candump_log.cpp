#include "io/candump_log.hpp"

#include <fmt/format.h>

#include <cerrno>
#include <cmath>
#include <cstring>
#include <stdexcept>
#include <system_error>

#include "io/input_error.hpp"
#include "io/text_file.hpp"

namespace bms {

namespace {

constexpr std::uint32_t kStdIdMax = 0x7FF;
constexpr std::uint32_t kExtIdMax = 0x1FFFFFFF;
constexpr std::uint32_t kErrFlag = 0x20000000;  // Linux CAN_ERR_FLAG, as candump prints it
constexpr std::size_t kMaxIntegerDigits = 12;
constexpr std::size_t kMaxFractionDigits = 9;
constexpr std::size_t kMaxData = 8;

bool is_space(char c) { return c == ' ' || c == '\t'; }
bool is_digit(char c) { return c >= '0' && c <= '9'; }

int hex_value(char c) {
  if (c >= '0' && c <= '9') return c - '0';
  if (c >= 'A' && c <= 'F') return c - 'A' + 10;
  if (c >= 'a' && c <= 'f') return c - 'a' + 10;
  return -1;
}

// A token as it appears in a message: control bytes escaped (a log can hold anything),
// long tokens shortened.
std::string shown(std::string_view token) {
  constexpr std::size_t kShown = 40;
  std::string out = "'";
  for (std::size_t i = 0; i < token.size() && i < kShown; ++i) {
    const char c = token[i];
    if (c >= 0x20 && c < 0x7F) {
      out += c;
    } else {
      out += fmt::format("\\x{:02x}", static_cast<unsigned char>(c));
    }
  }
  if (token.size() > kShown) out += "...";
  out += "'";
  return out;
}

class LineParser {
 public:
  LineParser(std::string_view line, std::string_view name, std::size_t line_number)
      : line_(line), name_(name), line_number_(line_number) {}

  CanLogEntry run() {
    std::string_view tokens[3];
    std::size_t count = 0;
    std::string_view rest = line_;
    for (;;) {
      while (!rest.empty() && is_space(rest.front())) rest.remove_prefix(1);
      if (rest.empty()) break;
      std::size_t end = 0;
      while (end < rest.size() && !is_space(rest[end])) ++end;
      if (count == 3) fail("unexpected text after the frame: " + shown(rest.substr(0, end)));
      tokens[count++] = rest.substr(0, end);
      rest.remove_prefix(end);
    }
    if (count < 3) fail("expected '(TIME) INTERFACE FRAME', e.g. '(1700000000.123456) vcan0 123#DEADBEEF'");
    CanLogEntry e;
    e.time_s = time(tokens[0]);
    e.interface = interface(tokens[1]);
    frame(tokens[2], e);
    return e;
  }

 private:
  double time(std::string_view token) const {
    const std::string problem = "bad timestamp " + shown(token) + " (expected '(SECONDS.FRACTION)')";
    if (token.size() < 3 || token.front() != '(' || token.back() != ')') fail(problem);
    const std::string_view t = token.substr(1, token.size() - 2);
    std::size_t i = 0;
    std::uint64_t seconds = 0;
    while (i < t.size() && is_digit(t[i])) {
      if (i == kMaxIntegerDigits) fail(problem);
      seconds = seconds * 10u + static_cast<std::uint64_t>(t[i] - '0');
      ++i;
    }
    if (i == 0) fail(problem);
    if (i == t.size()) return static_cast<double>(seconds);
    if (t[i] != '.' || i + 1 == t.size()) fail(problem);
    std::uint64_t fraction = 0;
    double scale = 1.0;
    for (std::size_t j = i + 1; j < t.size(); ++j) {
      if (!is_digit(t[j]) || j - i > kMaxFractionDigits) fail(problem);
      fraction = fraction * 10u + static_cast<std::uint64_t>(t[j] - '0');
      scale *= 10.0;
    }
    return static_cast<double>(seconds) + static_cast<double>(fraction) / scale;
  }

  std::string interface(std::string_view token) const {
    if (token.size() > kCanLogMaxInterface) {
      fail(fmt::format("interface name {} longer than {} characters", shown(token), kCanLogMaxInterface));
    }
    for (char c : token) {
      if (c < 0x21 || c > 0x7E) fail("interface name " + shown(token) + " holds a non-printable byte");
    }
    return std::string(token);
  }

  void frame(std::string_view token, CanLogEntry& e) const {
    const std::size_t hash = token.find('#');
    if (hash == std::string_view::npos) fail("frame " + shown(token) + " has no '#' (expected ID#DATA)");
    const std::string_view id = token.substr(0, hash);
    std::string_view body = token.substr(hash + 1);
    if (id.size() != 3 && id.size() != 8) {
      fail("identifier " + shown(id) + " must have 3 (11-bit) or 8 (29-bit) hex digits");
    }
    std::uint32_t value = 0;
    for (char c : id) {
      const int v = hex_value(c);
      if (v < 0) fail("identifier " + shown(id) + " is not hexadecimal");
      value = (value << 4u) | static_cast<std::uint32_t>(v);
    }
    e.extended_id = id.size() == 8;
    if (!e.extended_id && value > kStdIdMax) {
      fail(fmt::format("11-bit identifier 0x{:03X} above 0x7FF", value));
    }
    if (e.extended_id && (value & kErrFlag) != 0u) {
      fail(fmt::format("error frame (identifier 0x{:08X} has CAN_ERR_FLAG): not supported", value));
    }
    if (e.extended_id && value > kExtIdMax) {
      fail(fmt::format("29-bit identifier 0x{:08X} above 0x1FFFFFFF", value));
    }
    e.id = value;

    if (!body.empty() && body.front() == '#') fail("CAN FD frame " + shown(token) + ": not supported (classic CAN only)");
    if (!body.empty() && (body.front() == 'R' || body.front() == 'r')) {
      e.remote = true;
      body.remove_prefix(1);
      if (body.empty()) return;
      if (body.size() != 1 || body[0] < '0' || body[0] > '8') {
        fail("remote frame " + shown(token) + ": the length after 'R' must be one digit 0..8");
      }
      e.dlc = static_cast<std::uint8_t>(body[0] - '0');
      return;
    }
    std::size_t n = 0;
    std::size_t i = 0;
    while (i < body.size()) {
      if (n > 0 && body[i] == '.') {
        ++i;  // cansend's optional separator between bytes
        if (i == body.size()) fail("frame " + shown(token) + " ends with '.'");
      }
      if (body[i] == '_') fail("frame " + shown(token) + ": a DLC above 8 ('_' suffix) is not supported");
      if (i + 1 >= body.size()) fail("frame " + shown(token) + ": odd number of hex digits in the data");
      const int hi = hex_value(body[i]);
      const int lo = hex_value(body[i + 1]);
      if (hi < 0 || lo < 0) fail("frame " + shown(token) + ": data is not hexadecimal");
      if (n == kMaxData) fail("frame " + shown(token) + ": more than 8 data bytes (classic CAN only)");
      e.data[n++] = static_cast<std::uint8_t>(hi * 16 + lo);
      i += 2;
    }
    e.dlc = static_cast<std::uint8_t>(n);
  }

  [[noreturn]] void fail(const std::string& problem) const {
    throw InputError(fmt::format("{}: line {}: {}", name_, line_number_, problem));
  }

  std::string_view line_;
  std::string_view name_;
  std::size_t line_number_;
};

}  // namespace

CanLogEntry parse_candump_line(std::string_view line, std::string_view name, std::size_t line_number) {
  return LineParser(line, name, line_number).run();
}

std::vector<CanLogEntry> parse_candump_log(std::string_view text, std::string_view name) {
  std::vector<CanLogEntry> entries;
  std::size_t line_number = 0;
  while (!text.empty()) {
    ++line_number;
    const std::size_t nl = text.find('\n');
    std::string_view line = text.substr(0, nl);
    text.remove_prefix(nl == std::string_view::npos ? text.size() : nl + 1);
    if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
    bool blank = true;
    for (char c : line) blank = blank && is_space(c);
    if (blank) continue;
    entries.push_back(parse_candump_line(line, name, line_number));
  }
  return entries;
}

std::vector<CanLogEntry> read_candump_log(const std::filesystem::path& file) {
  return parse_candump_log(read_text_file(file), file.string());
}

std::string format_candump_line(const CanLogEntry& e) {
  if (!std::isfinite(e.time_s) || e.time_s < 0.0 || e.time_s >= 1e12) {
    throw std::invalid_argument(fmt::format("candump entry: time {} s not in [0, 1e12)", e.time_s));
  }
  if (e.interface.empty() || e.interface.size() > kCanLogMaxInterface) {
    throw std::invalid_argument(fmt::format("candump entry: interface name '{}' must have 1..{} characters",
                                            e.interface, kCanLogMaxInterface));
  }
  for (char c : e.interface) {
    if (c < 0x21 || c > 0x7E) {
      throw std::invalid_argument("candump entry: interface name holds a space or a non-printable byte");
    }
  }
  if (e.dlc > kMaxData) throw std::invalid_argument(fmt::format("candump entry: dlc {} above 8", e.dlc));
  if (e.id > (e.extended_id ? kExtIdMax : kStdIdMax)) {
    throw std::invalid_argument(fmt::format("candump entry: identifier 0x{:X} out of range", e.id));
  }
  // Whole seconds and microseconds as integers: no rounding up to "x.1000000".
  double whole = std::floor(e.time_s);
  auto micro = static_cast<long long>(std::llround((e.time_s - whole) * 1e6));
  if (micro >= 1000000) {
    whole += 1.0;
    micro -= 1000000;
  }
  std::string out = fmt::format("({}.{:06d}) {} ", static_cast<long long>(whole), micro, e.interface);
  out += e.extended_id ? fmt::format("{:08X}#", e.id) : fmt::format("{:03X}#", e.id);
  if (e.remote) {
    out += 'R';
    if (e.dlc > 0) out += static_cast<char>('0' + e.dlc);
    return out;
  }
  for (std::size_t i = 0; i < e.dlc; ++i) out += fmt::format("{:02X}", e.data[i]);
  return out;
}

CandumpWriter::CandumpWriter(std::filesystem::path file) : out_(std::move(file)) {}

void CandumpWriter::write(const CanLogEntry& entry) {
  out_.append(format_candump_line(entry) + "\n");
  ++lines_;
}

void CandumpWriter::commit() { out_.commit(); }

}  // namespace bms
