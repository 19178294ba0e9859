#include "io/csv_table.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <limits>
#include <string>

#include "io/input_error.hpp"
#include "io/text_file.hpp"

namespace bms {
namespace {

namespace fs = std::filesystem;

std::string csv_error(std::string_view text, std::string_view column) {
  try {
    const CsvTable t = parse_csv(text, "data.csv", {"mode"});
    (void)t.numbers(column);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

// A fresh directory per test, removed afterwards.
class CsvWriterTest : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() /
           fmt::format("bms_io_test_{}_{}", ::getpid(),
                       ::testing::UnitTest::GetInstance()->current_test_info()->name());
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }
  fs::path dir_;
};

TEST(CsvTable, ParsesNumbersAndTextColumns) {
  const CsvTable t =
      parse_csv("t_s, mode ,v\n0,rest,1.5\n0.5,cc_charge,-2e-3\n", "data.csv", {"mode"});
  EXPECT_EQ(t.name(), "data.csv");
  EXPECT_EQ(t.columns(), (std::vector<std::string>{"t_s", "mode", "v"}));
  EXPECT_EQ(t.rows(), 2u);
  EXPECT_TRUE(t.has("v"));
  EXPECT_FALSE(t.has("w"));
  EXPECT_EQ(t.numbers("t_s"), (std::vector<double>{0.0, 0.5}));
  EXPECT_EQ(t.numbers("v"), (std::vector<double>{1.5, -2e-3}));
  EXPECT_EQ(t.strings("mode"), (std::vector<std::string>{"rest", "cc_charge"}));
  EXPECT_EQ(t.where(1, "v"), "data.csv: line 3, column 3 ('v')");
  EXPECT_THROW((void)t.strings("v"), std::logic_error);
}

TEST(CsvTable, AcceptsBomCrlfBlankTrailingLinesAndNoFinalNewline) {
  const CsvTable a = parse_csv("\xEF\xBB\xBFTime [s],I[A]\r\n0,-1\r\n1,+2\r\n\r\n  \n\n", "a.csv");
  EXPECT_EQ(a.columns()[0], "Time [s]");
  EXPECT_EQ(a.rows(), 2u);
  EXPECT_EQ(a.numbers("I[A]"), (std::vector<double>{-1.0, 2.0}));
  const CsvTable b = parse_csv("x\n1\n2", "b.csv");
  EXPECT_EQ(b.numbers("x"), (std::vector<double>{1.0, 2.0}));
  const CsvTable header_only = parse_csv("x,y\n", "c.csv");
  EXPECT_EQ(header_only.rows(), 0u);
  EXPECT_TRUE(header_only.numbers("y").empty());
}

TEST(CsvTable, BadCellsNameFileLineAndColumn) {
  const std::string head = "t_s,current_a,mode\n0,1,rest\n";
  EXPECT_EQ(csv_error(head + "1,abc,rest\n", "current_a"),
            "data.csv: line 3, column 2 ('current_a'): not a number: 'abc'");
  EXPECT_EQ(csv_error(head + "1,1.5A,rest\n", "current_a"),
            "data.csv: line 3, column 2 ('current_a'): not a number: '1.5A'");
  EXPECT_EQ(csv_error(head + "1,nan,rest\n", "current_a"),
            "data.csv: line 3, column 2 ('current_a'): not a finite number: 'nan'");
  EXPECT_EQ(csv_error(head + "1,-inf,rest\n", "current_a"),
            "data.csv: line 3, column 2 ('current_a'): not a finite number: '-inf'");
  EXPECT_EQ(csv_error(head + "1, ,rest\n", "current_a"),
            "data.csv: line 3, column 2 ('current_a'): empty cell");
  EXPECT_EQ(csv_error(head + "1,1e999,rest\n", "current_a"),
            "data.csv: line 3, column 2 ('current_a'): number out of range: '1e999'");
  EXPECT_EQ(csv_error(head + "1,+-1,rest\n", "current_a"),
            "data.csv: line 3, column 2 ('current_a'): not a number: '+-1'");
  EXPECT_EQ(csv_error(head + "1,0x10,rest\n", "current_a"),
            "data.csv: line 3, column 2 ('current_a'): not a number: '0x10'");
  // Only the columns a caller asks for must be clean.
  EXPECT_EQ(csv_error(head + "1,abc,rest\n", "t_s"), "(no error)");
  EXPECT_EQ(csv_error(head, "voltage_v"),
            "data.csv: line 1: missing column 'voltage_v' (the header has: t_s, current_a, mode)");
}

TEST(CsvTable, NanCellsOnlyWhereTheCallerAllowsThem) {
  const CsvTable t = parse_csv("a,b\n1,nan\n2,3\n", "data.csv");
  const auto& b = t.numbers_or_nan("b");
  ASSERT_EQ(b.size(), 2u);
  EXPECT_TRUE(std::isnan(b[0]));
  EXPECT_EQ(b[1], 3.0);
  EXPECT_THROW((void)t.numbers("b"), InputError) << "numbers() still refuses a nan";
  const CsvTable bad = parse_csv("a,b\n1,nan\n2,inf\n3,x\n", "data.csv");
  try {
    (void)bad.numbers_or_nan("b");
    FAIL() << "inf accepted";
  } catch (const InputError& e) {
    EXPECT_STREQ(e.what(), "data.csv: line 3, column 2 ('b'): not a finite number: 'inf'");
  }
}

TEST(CsvTable, StructuralErrors) {
  EXPECT_EQ(csv_error("a,b\n1,2\n3\n", "a"),
            "data.csv: line 3: 1 cells, but the header has 2 columns");
  EXPECT_EQ(csv_error("a,b\n1,2,3\n", "a"),
            "data.csv: line 2: 3 cells, but the header has 2 columns");
  EXPECT_EQ(csv_error("a,b\n1,2\n\n3,4\n", "a"), "data.csv: line 3: blank line inside the data");
  EXPECT_EQ(csv_error("a,a\n1,2\n", "a"), "data.csv: line 1, column 2: duplicate column name 'a'");
  EXPECT_EQ(csv_error("a,,b\n1,2,3\n", "a"), "data.csv: line 1, column 2: empty column name");
  EXPECT_EQ(csv_error("", "a"), "data.csv: empty file (expected a header line)");
  EXPECT_EQ(csv_error("\r\n\n", "a"), "data.csv: empty file (expected a header line)");
  EXPECT_THROW(read_csv(BMS_SOURCE_DIR "/no/such.csv"), InputError);
}

TEST_F(CsvWriterTest, WritesOnlyOnCommitAndRoundTripsDoubles) {
  const fs::path file = dir_ / "out.csv";
  const std::vector<double> values = {0.1, 1.0 / 3.0, -2.5e17, 1e-300, 3.0, -0.0};
  {
    CsvWriter w(file, {"t_s", "mode", "cycle", "v"});
    for (std::size_t i = 0; i < values.size(); ++i) {
      w.cell(0.2 * static_cast<double>(i)).cell("rest").cell(static_cast<int>(i)).cell(values[i]);
      w.end_row();
    }
    EXPECT_EQ(w.path(), file);
    EXPECT_FALSE(fs::exists(file));
    w.commit();
    EXPECT_FALSE(fs::exists(dir_ / "out.csv.tmp"));
  }
  const CsvTable t = read_csv(file, {"mode"});
  EXPECT_EQ(t.rows(), values.size());
  EXPECT_EQ(t.numbers("v"), values);  // bit-exact round trip
  EXPECT_EQ(t.numbers("cycle")[4], 4.0);
  EXPECT_EQ(t.strings("mode")[0], "rest");
  EXPECT_EQ(read_text_file(file).substr(0, 19), "t_s,mode,cycle,v\n0,");
}

TEST_F(CsvWriterTest, AbandonedWriterLeavesNothing) {
  const fs::path file = dir_ / "out.csv";
  {
    CsvWriter w(file, {"a"});
    w.cell(1.0).end_row();
    EXPECT_TRUE(fs::exists(dir_ / "out.csv.tmp"));
  }
  EXPECT_FALSE(fs::exists(file));
  EXPECT_FALSE(fs::exists(dir_ / "out.csv.tmp"));
}

TEST_F(CsvWriterTest, MisuseIsReported) {
  CsvWriter w(dir_ / "x.csv", {"a", "b"});
  w.cell(1.0);
  EXPECT_THROW(w.end_row(), std::logic_error);
  EXPECT_THROW(w.cell("a,b"), std::invalid_argument);
  EXPECT_THROW(CsvWriter(dir_ / "y.csv", {"bad,name"}), std::invalid_argument);
  EXPECT_FALSE(fs::exists(dir_ / "y.csv.tmp"));
  EXPECT_THROW(CsvWriter(dir_ / "missing_dir" / "z.csv", {"a"}), InputError);
}

}  // namespace
}  // namespace bms
