// Regression tests for what the fuzzers (tests/fuzz, scripts/fuzz.sh) found in the input
// parsers, and a check that the hand-written seed inputs stay valid input (a seed that no
// longer parses would quietly cost the fuzzer its best starting point).
#include <gtest/gtest.h>

#include <string>

#include "io/bpx_reader.hpp"
#include "io/candump_log.hpp"
#include "io/csv_table.hpp"
#include "io/expression.hpp"
#include "io/input_error.hpp"
#include "io/measured_profile.hpp"
#include "io/text_file.hpp"

namespace bms {
namespace {

const std::string kCorpus = BMS_SOURCE_DIR "/tests/fuzz/corpus";

std::string bpx_error(std::string_view text) {
  try {
    (void)read_bpx_text(text, "cell.json");
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

// fuzz_bpx, first seconds: a number beyond double's range made nlohmann::json throw
// out_of_range (not parse_error), which escaped read_bpx_text as a non-InputError
// exception: bmssim would have reported a runtime failure (exit 1) instead of bad input (2).
TEST(FuzzRegressions, BpxNumberOutOfDoubleRangeIsAnInputError) {
  EXPECT_EQ(bpx_error("[1, 2.5e308]"), "cell.json: not valid JSON: number overflow parsing '2.5e308'");
  EXPECT_EQ(bpx_error(R"({"Header": {"BPX": -1e999}})"),
            "cell.json: not valid JSON: number overflow parsing '-1e999'");
}

TEST(FuzzRegressions, HandWrittenSeedsAreValidInput) {
  const CellParameters p = read_bpx(kCorpus + "/bpx/minimal_valid.json");
  EXPECT_DOUBLE_EQ(p.electrode_area_m2, 0.1);
  EXPECT_TRUE(p.negative.entropic_v_k != nullptr);

  const auto log = read_candump_log(kCorpus + "/candump/mixed.log");
  EXPECT_EQ(log.size(), 8u);

  for (const char* e : {"ocp_fit.txt", "electrolyte_diffusivity.txt", "mixed_functions.txt", "hyperbolic.txt",
                        "nesting_signs.txt"}) {
    EXPECT_NO_THROW(ExpressionFunction::parse(read_text_file(kCorpus + "/expression/" + e), e)) << e;
  }
  // CSV seeds: the first byte selects the reader in fuzz_csv ('0' table, '1' truth columns,
  // '2' measured columns); the rest is the file.
  for (const char* f : {"table.csv", "truth_profile.csv", "truth_measured_crlf.csv", "aboutenergy_bom.csv",
                        "aboutenergy_kelvin.csv"}) {
    const std::string text = read_text_file(kCorpus + "/csv/" + f);
    ASSERT_FALSE(text.empty()) << f;
    const std::string_view body = std::string_view(text).substr(1);
    if (text[0] == '0') {
      EXPECT_NO_THROW((void)parse_csv(body, f, {"mode"}).numbers("a")) << f;
    } else {
      const auto which = text[0] == '1' ? ProfileColumns::truth : ProfileColumns::measured;
      EXPECT_NO_THROW((void)parse_measured_profile(body, f, which)) << f;
    }
  }
}

}  // namespace
}  // namespace bms
