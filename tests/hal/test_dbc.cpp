// The DBC file (firmware/can/bms.dbc) against the codec's layout table: every message id,
// name, length and sender, and every signal's start bit, length, byte order, signedness,
// value type, factor, offset, range, unit and receiver must match, in both directions.
#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iterator>
#include <map>
#include <regex>
#include <set>
#include <sstream>
#include <string>
#include <vector>

#include "bms/fw/can/can_protocol.hpp"

namespace can = bms::fw::can;

namespace {

struct DbcSignal {
  std::string name;
  int start_bit = 0;
  int length = 0;
  int byte_order = 0;  // 1 = Intel (little-endian), 0 = Motorola
  bool is_signed = false;
  double factor = 0, offset = 0, min = 0, max = 0;
  std::string unit;
  std::string receivers;
  int value_type = 0;  // SIG_VALTYPE_: 0 integer, 1 float32, 2 float64
  int line = 0;
};

struct DbcMessage {
  std::uint32_t id = 0;
  std::string name;
  int dlc = 0;
  std::string sender;
  std::vector<DbcSignal> signals;
  int line = 0;
};

struct Dbc {
  std::vector<std::string> nodes;
  std::map<std::uint32_t, DbcMessage> messages;
};

// A small reader for the parts of a DBC this project uses: BU_, BO_, SG_, SIG_VALTYPE_.
Dbc read_dbc(const std::string& path) {
  std::ifstream in(path);
  EXPECT_TRUE(in.good()) << "cannot open " << path;
  const std::regex bu(R"(^BU_\s*:\s*(.*)$)");
  const std::regex bo(R"(^BO_\s+(\d+)\s+(\w+)\s*:\s*(\d+)\s+(\w+)\s*$)");
  const std::regex sg(
      R"(^\s+SG_\s+(\w+)\s*:\s*(\d+)\|(\d+)@([01])([+-])\s*\(\s*([^,\s]+)\s*,\s*([^)\s]+)\s*\)\s*\[\s*([^|\s]+)\s*\|\s*([^\]\s]+)\s*\]\s*\"([^\"]*)\"\s*(.*?)\s*$)");
  const std::regex vt(R"(^SIG_VALTYPE_\s+(\d+)\s+(\w+)\s*:\s*(\d)\s*;\s*$)");
  Dbc dbc;
  DbcMessage* current = nullptr;
  std::string line;
  int n = 0;
  while (std::getline(in, line)) {
    ++n;
    if (!line.empty() && line.back() == '\r') line.pop_back();
    std::smatch m;
    if (std::regex_match(line, m, bu)) {
      std::istringstream ss(m[1].str());
      std::string node;
      while (ss >> node) dbc.nodes.push_back(node);
    } else if (std::regex_match(line, m, bo)) {
      DbcMessage msg;
      msg.id = static_cast<std::uint32_t>(std::stoul(m[1].str()));
      msg.name = m[2].str();
      msg.dlc = std::stoi(m[3].str());
      msg.sender = m[4].str();
      msg.line = n;
      EXPECT_EQ(dbc.messages.count(msg.id), 0u) << "duplicate BO_ " << msg.id << " at line " << n;
      current = &(dbc.messages[msg.id] = msg);
    } else if (std::regex_match(line, m, sg)) {
      EXPECT_NE(current, nullptr) << "SG_ outside BO_ at line " << n;
      if (current == nullptr) continue;
      DbcSignal s;
      s.name = m[1].str();
      s.start_bit = std::stoi(m[2].str());
      s.length = std::stoi(m[3].str());
      s.byte_order = std::stoi(m[4].str());
      s.is_signed = m[5].str() == "-";
      s.factor = std::stod(m[6].str());
      s.offset = std::stod(m[7].str());
      s.min = std::stod(m[8].str());
      s.max = std::stod(m[9].str());
      s.unit = m[10].str();
      s.receivers = m[11].str();
      s.line = n;
      current->signals.push_back(s);
    } else if (std::regex_match(line, m, vt)) {
      const auto msg_id = static_cast<std::uint32_t>(std::stoul(m[1].str()));
      bool found = false;
      auto it = dbc.messages.find(msg_id);
      if (it != dbc.messages.end())
        for (auto& s : it->second.signals)
          if (s.name == m[2].str()) {
            s.value_type = std::stoi(m[3].str());
            found = true;
          }
      EXPECT_TRUE(found) << "SIG_VALTYPE_ for unknown signal at line " << n;
    } else {
      // Any other line that mentions SG_ or BO_ at its start must have been understood.
      const bool unparsed_sg = std::regex_search(line, std::regex(R"(^\s+SG_\s)"));
      const bool unparsed_bo = std::regex_search(line, std::regex(R"(^BO_\s)"));
      EXPECT_FALSE(unparsed_sg || unparsed_bo) << "unparsed line " << n << ": " << line;
      if (!line.empty() && line[0] != ' ' && line[0] != '\t') current = nullptr;
    }
  }
  return dbc;
}

std::string dbc_path() { return std::string(BMS_SOURCE_DIR) + "/firmware/can/bms.dbc"; }

const char* node_name(can::Node n) { return n == can::Node::bms ? "BMS" : "HOST"; }

void expect_close(double dbc, double code, const std::string& what) {
  const double tol = 1e-12 * std::max(1.0, std::fabs(code));
  EXPECT_NEAR(dbc, code, tol) << what;
}

}  // namespace

TEST(Dbc, NodesAreBmsAndHost) {
  const Dbc dbc = read_dbc(dbc_path());
  EXPECT_EQ(dbc.nodes, (std::vector<std::string>{"BMS", "HOST"}));
}

TEST(Dbc, EveryCodecMessageIsInTheDbcAndViceVersa) {
  const Dbc dbc = read_dbc(dbc_path());
  std::set<std::uint32_t> code_ids;
  for (const auto& m : can::kMessages) code_ids.insert(m.id);
  std::set<std::uint32_t> dbc_ids;
  for (const auto& kv : dbc.messages) dbc_ids.insert(kv.first);
  EXPECT_EQ(code_ids, dbc_ids);
  EXPECT_EQ(code_ids.size(), can::kMessageCount) << "duplicate ids in kMessages";
}

TEST(Dbc, MessagesAndSignalsMatchTheCodecLayout) {
  const Dbc dbc = read_dbc(dbc_path());
  for (const auto& cm : can::kMessages) {
    SCOPED_TRACE(cm.name);
    auto it = dbc.messages.find(cm.id);
    ASSERT_NE(it, dbc.messages.end()) << "message " << cm.name << " missing from the DBC";
    const DbcMessage& dm = it->second;
    EXPECT_EQ(dm.name, cm.name);
    EXPECT_EQ(dm.dlc, cm.dlc);
    EXPECT_EQ(dm.sender, node_name(cm.sender));
    EXPECT_LE(cm.id, 0x7FFu) << "classic 11-bit identifier";
    ASSERT_EQ(dm.signals.size(), cm.signal_count) << "signal count differs";
    for (std::size_t i = 0; i < cm.signal_count; ++i) {
      const can::SignalLayout& cs = cm.signals[i];
      const DbcSignal* ds = nullptr;
      for (const auto& s : dm.signals)
        if (s.name == cs.name) ds = &s;
      ASSERT_NE(ds, nullptr) << "signal " << cs.name << " missing from the DBC";
      const std::string where = std::string(cm.name) + "." + cs.name + " (dbc line " + std::to_string(ds->line) + ")";
      EXPECT_EQ(ds->start_bit, cs.start_bit) << where;
      EXPECT_EQ(ds->length, cs.length) << where;
      EXPECT_EQ(ds->byte_order, can::kSignalsLittleEndian ? 1 : 0) << where;
      EXPECT_EQ(ds->is_signed, cs.type != can::ValueType::unsigned_int) << where;
      EXPECT_EQ(ds->value_type, cs.type == can::ValueType::float32 ? 1 : 0) << where;
      expect_close(ds->factor, cs.factor, where + " factor");
      expect_close(ds->offset, cs.offset, where + " offset");
      expect_close(ds->min, cs.min, where + " min");
      expect_close(ds->max, cs.max, where + " max");
      EXPECT_EQ(ds->unit, cs.unit) << where;
      EXPECT_EQ(ds->receivers, node_name(cm.receiver)) << where;
    }
  }
}

TEST(Dbc, DocumentsTheCrcAndCounter) {
  std::ifstream in(dbc_path());
  const std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  EXPECT_NE(text.find("CRC-8/SAE-J1850"), std::string::npos);
  EXPECT_NE(text.find("0x1D"), std::string::npos);
  EXPECT_NE(text.find("alive counter"), std::string::npos);
  EXPECT_NE(text.find("SIG_VALTYPE_"), std::string::npos);
}
