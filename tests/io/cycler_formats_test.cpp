// The cycler readers: a small file written in each layout, read back with our sign convention
// (positive = discharge), and a malformed file of each layout refused with its line and column.
#include "io/cycler_formats.hpp"

#include <gtest/gtest.h>
#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <string>
#include <vector>

#include "io/delimited_table.hpp"
#include "io/input_error.hpp"

namespace bms {
namespace {

namespace fs = std::filesystem;

// One cycle as a cycler logs it: rest, CC charge (voltage rising), rest, CC discharge (falling).
struct Sample {
  double t_s, current_a /* charge positive */, voltage_v;
  int step;
  char state;  // R, C, D
};
std::vector<Sample> one_cycle(double t0_s, double dt_s) {
  std::vector<Sample> s;
  double t = t0_s;
  for (int k = 0; k < 3; ++k, t += dt_s) s.push_back({t, 0.0, 3.40, 1, 'R'});
  for (int k = 0; k < 14; ++k, t += dt_s) s.push_back({t, 0.55, 3.60 + 0.04 * k, 2, 'C'});
  for (int k = 0; k < 3; ++k, t += dt_s) s.push_back({t, 0.0, 4.10 - 0.01 * k, 3, 'R'});
  for (int k = 0; k < 14; ++k, t += dt_s) s.push_back({t, -1.1, 3.95 - 0.06 * k, 4, 'D'});
  return s;
}

fs::path write(const std::string& name, const std::string& text) {
  const fs::path dir = fs::path(::testing::TempDir()) / "cycler_formats";
  fs::create_directories(dir);
  const fs::path p = dir / name;
  std::ofstream(p, std::ios::binary) << text;
  return p;
}

std::string error_of(const std::function<void()>& f) {
  try {
    f();
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

std::string date(double epoch_offset_s) {  // 2010-10-08 14:00:00 + offset, whole seconds
  const int s = static_cast<int>(epoch_offset_s);
  return fmt::format("2010-10-{:02d} {:02d}:{:02d}:{:02d}", 8 + (14 * 3600 + s) / 86400, ((14 * 3600 + s) / 3600) % 24,
                     (s / 60) % 60, s % 60);
}

std::string arbin(const std::vector<Sample>& cycle, int cycles, double start_s, double gap_at_s = -1) {
  std::string out =
      "Data_Point,Test_Time(s),Date_Time,Step_Time(s),Step_Index,Cycle_Index,Current(A),Voltage(V),"
      "Charge_Capacity(Ah),Discharge_Capacity(Ah),Internal_Resistance(Ohm)\n";
  int point = 1;
  double period = cycle.back().t_s + (cycle[1].t_s - cycle[0].t_s), q_dis = 0.0, q_ch = 0.0;
  for (int c = 0; c < cycles; ++c)
    for (const Sample& s : cycle) {
      double t = s.t_s + c * period;
      if (gap_at_s >= 0 && t >= gap_at_s) t += 600.0;
      (s.current_a > 0 ? q_ch : q_dis) += std::abs(s.current_a) * 30.0 / 3600.0;
      out += fmt::format("{},{},{},0,{},{},{},{},{},{},{}\n", point++, t, date(start_s + t), s.step, c + 1, s.current_a,
                         s.voltage_v, q_ch, q_dis, 0.09 + 0.001 * c);
    }
  return out;
}

TEST(CyclerFormats, ArbinFilesJoinedInTimeOrderWithGapsAndCycles) {
  const auto cycle = one_cycle(30.0, 30.0);
  // Given in reverse order: the second test started a day after the first.
  const fs::path later = write("arbin_b.csv", arbin(cycle, 1, 86400.0));
  const fs::path first = write("arbin_a.csv", arbin(cycle, 2, 0.0, 1200.0));
  EXPECT_EQ(detect_cycler_layout_of(first).layout, CyclerLayout::arbin);
  const CyclerRecord r = read_cycler_record({later, first}, CurrentSign::by_layout);
  ASSERT_EQ(r.files.size(), 2u);
  EXPECT_EQ(r.files.front(), first.string());
  ASSERT_EQ(r.t_s.size(), 3 * cycle.size());
  EXPECT_EQ(r.layout, "Arbin");
  // Charge-positive in the file: the 0.55 A charge is -0.55 A here, the discharge +1.1 A.
  EXPECT_DOUBLE_EQ(r.current_a[5], -0.55);
  EXPECT_DOUBLE_EQ(r.current_a[cycle.size() - 1], 1.1);
  // Cycles numbered on: 1, 2 in the first file, 3 in the second.
  EXPECT_EQ(r.cycle.front(), 1);
  EXPECT_EQ(r.cycle[cycle.size()], 2);
  EXPECT_EQ(r.cycle.back(), 3);
  EXPECT_EQ(r.step[5], 2);
  ASSERT_EQ(r.step_time_s.size(), r.t_s.size());  // Step_Time(s) kept for the discharge-onset resistance
  // Segments: the start, the 600 s logging gap (in the second cycle's charge) and the day
  // between the files (the first file ends in a discharge: under current too).
  ASSERT_EQ(r.segment_starts.size(), 3u);
  EXPECT_EQ(r.gaps, 2u);
  EXPECT_EQ(r.gaps_under_current, 2u);
  const std::size_t g = r.segment_starts[1];
  EXPECT_NEAR(r.t_s[g] - r.t_s[g - 1], 630.0, 1e-9);
  EXPECT_LT(r.current_a[g], 0.0);
  EXPECT_NEAR(r.t_s[2 * cycle.size()] - r.t_s.front(), 86400.0, 1.0);
  // The cycler's own numbers per cycle, renumbered.
  ASSERT_EQ(r.cycle_stats.size(), 3u);
  EXPECT_EQ(r.cycle_stats[2].cycle, 3);
  EXPECT_NEAR(r.cycle_stats[0].discharge_ah, 14 * 1.1 * 30.0 / 3600.0, 1e-9);
  EXPECT_NEAR(r.cycle_stats[1].internal_resistance_ohm, 0.091, 1e-12);
}

TEST(CyclerFormats, ArbinMalformedRefusedAtTheLineAndColumn) {
  const auto cycle = one_cycle(30.0, 30.0);
  std::string text = arbin(cycle, 1, 0.0);
  // The third data row (line 4): its voltage (column 8) made unreadable.
  const auto row = text.find("\n3,90,");
  ASSERT_NE(row, std::string::npos);
  text.replace(text.find(",3.4,", row), 5, ",3.x,");
  const fs::path bad = write("arbin_bad.csv", text);
  EXPECT_EQ(error_of([&] { read_cycler_record({bad}, CurrentSign::by_layout); }),
            bad.string() + ": line 4, column 8 ('Voltage(V)'): not a finite number: '3.x'");
  // Time going back.
  std::string back = arbin(cycle, 1, 0.0);
  const auto p = back.find("\n4,120,");
  ASSERT_NE(p, std::string::npos);
  back.replace(p, 7, "\n4,60,");
  const fs::path bad_time = write("arbin_back.csv", back);
  EXPECT_NE(error_of([&] { read_cycler_record({bad_time}, CurrentSign::by_layout); })
                .find("line 5, column 2 ('Test_Time(s)'): time 60 s goes back from the previous row's 90 s"),
            std::string::npos);
  // The same data twice: overlapping records.
  const fs::path a = write("arbin_dup1.csv", arbin(cycle, 1, 0.0)), b = write("arbin_dup2.csv", arbin(cycle, 1, 0.0));
  EXPECT_NE(error_of([&] { read_cycler_record({a, b}, CurrentSign::by_layout); }).find("overlapping"), std::string::npos);
}

TEST(CyclerFormats, ASignThatContradictsTheVoltageIsRefused) {
  const fs::path f = write("arbin_sign.csv", arbin(one_cycle(30.0, 30.0), 1, 0.0));
  const std::string e = error_of([&] { read_cycler_record({f}, CurrentSign::discharge_positive); });
  EXPECT_NE(e.find("column 7 ('Current(A)'): the current's sign, read as discharge-positive (--current-sign), "
                   "contradicts the voltage"),
            std::string::npos)
      << e;
  EXPECT_NO_THROW(read_cycler_record({f}, CurrentSign::charge_positive));
}

std::string maccor(const std::vector<Sample>& cycle) {
  std::string out = "Today's Date\t10/09/2019\tDate of Test:\t10/08/2019\tFilename:\tcell.001\tProcedure:\tcc.000\n"
                    "Rec#\tCyc#\tStep\tTest (Sec)\tStep (Sec)\tAmp-hr\tWatt-hr\tAmps\tVolts\tState\tES\tDPt Time\t\n";
  int rec = 1;
  for (const Sample& s : cycle)
    out += fmt::format("{}\t0\t{}\t{}\t0\t0\t0\t{}\t{}\t{}\t0\t10/08/2019 2:{:02d}:{:02d} PM\t\n", rec++, s.step, s.t_s,
                       std::abs(s.current_a), s.voltage_v, s.state, static_cast<int>(s.t_s) / 60 % 60,
                       static_cast<int>(s.t_s) % 60);
  return out;
}

TEST(CyclerFormats, MaccorMagnitudesSignedByState) {
  const auto cycle = one_cycle(0.0, 10.0);
  const fs::path f = write("cell.001.txt", maccor(cycle));
  EXPECT_EQ(detect_cycler_layout_of(f).layout, CyclerLayout::maccor);
  const CyclerRecord r = read_cycler_record({f}, CurrentSign::by_layout);
  ASSERT_EQ(r.t_s.size(), cycle.size());
  EXPECT_DOUBLE_EQ(r.current_a[5], -0.55);
  EXPECT_DOUBLE_EQ(r.current_a.back(), 1.1);
  EXPECT_EQ(r.step.back(), 4);
  EXPECT_NE(r.note.find("magnitude"), std::string::npos) << r.note;
  // A cell that is no number, on line 6 (the second data row after the metadata line and header
  // is line 4).
  std::string text = maccor(cycle);
  const auto p = text.find("\t3.4\tR", text.find("\n3\t"));
  text.replace(p + 1, 3, "3.4.1");
  const fs::path bad = write("bad.001.txt", text);
  EXPECT_EQ(error_of([&] { read_cycler_record({bad}, CurrentSign::by_layout); }),
            bad.string() + ": line 5, column 9 ('Volts'): not a finite number: '3.4.1'");
}

std::string neware(const std::vector<Sample>& cycle) {
  std::string out = "Record ID,Realtime,Total Time,Step ID,Cycle ID,Step Name,Current(mA),Voltage(V)\n";
  int rec = 1;
  for (const Sample& s : cycle) {
    const char* name = s.state == 'C' ? "CC_Chg" : s.state == 'D' ? "CC_DChg" : "Rest";
    const int t = static_cast<int>(s.t_s);
    out += fmt::format("{},2021-03-04 09:{:02d}:{:02d},{:02d}:{:02d}:{:02d}.000,{},1,{},{},{}\n", rec++, t / 60 % 60,
                       t % 60, t / 3600, t / 60 % 60, t % 60, s.step, name, s.current_a * 1000.0, s.voltage_v);
  }
  return out;
}

TEST(CyclerFormats, NewareMilliampsAndClockTimes) {
  const auto cycle = one_cycle(0.0, 60.0);
  const fs::path f = write("neware.csv", neware(cycle));
  EXPECT_EQ(detect_cycler_layout_of(f).layout, CyclerLayout::neware);
  const CyclerRecord r = read_cycler_record({f}, CurrentSign::by_layout);
  ASSERT_EQ(r.t_s.size(), cycle.size());
  EXPECT_DOUBLE_EQ(r.t_s[1] - r.t_s[0], 60.0);
  EXPECT_DOUBLE_EQ(r.current_a[5], -0.55);
  EXPECT_DOUBLE_EQ(r.current_a.back(), 1.1);
  EXPECT_NE(r.note.find("from the step types"), std::string::npos) << r.note;
  std::string text = neware(cycle);
  const auto p = text.find("00:03:00.000");
  text.replace(p, 12, "00:03:0x.000");
  const fs::path bad = write("neware_bad.csv", text);
  EXPECT_EQ(error_of([&] { read_cycler_record({bad}, CurrentSign::by_layout); }),
            bad.string() + ": line 5, column 3 ('Total Time'): not a time (a number, or [Nd ]H:MM:SS[.fff]): "
                           "'00:03:0x.000'");
  // A discharge step logged with the charge's sign.
  std::string flipped = neware(cycle);
  const auto d = flipped.rfind(",CC_DChg,-1100,");
  flipped.replace(d, 15, ",CC_DChg,1100,");
  const fs::path mixed = write("neware_mixed.csv", flipped);
  EXPECT_NE(error_of([&] { read_cycler_record({mixed}, CurrentSign::by_layout); })
                .find(fmt::format("line {}, column 7 ('Current(mA)'): current 1.1 A in a discharge step",
                                  cycle.size() + 1)),
            std::string::npos);
}

std::string biologic(const std::vector<Sample>& cycle) {
  std::string out = "EC-Lab ASCII FILE\nNb header lines : 5\n\nAcquisition started on : 07/29/2020 10:31:03.000\n"
                    "mode\tox/red\ttime/s\tEcell/V\t<I>/mA\tcycle number\tNs\n";
  for (const Sample& s : cycle) {
    std::string line = fmt::format("{}\t{}\t{:.4f}\t{:.6f}\t{:.3f}\t1\t{}\n", s.state == 'R' ? 3 : 1,
                                   s.current_a > 0 ? 1 : 0, s.t_s, s.voltage_v, s.current_a * 1000.0, s.step - 1);
    std::replace(line.begin(), line.end(), '.', ',');  // a French locale: decimal commas
    out += line;
  }
  return out;
}

TEST(CyclerFormats, BioLogicMptWithDecimalCommas) {
  const auto cycle = one_cycle(0.0, 5.0);
  const fs::path f = write("cell.mpt", biologic(cycle));
  const CyclerLayoutGuess g = detect_cycler_layout_of(f);
  EXPECT_EQ(g.layout, CyclerLayout::biologic);
  EXPECT_EQ(g.header_line, 4u);
  const CyclerRecord r = read_cycler_record({f}, CurrentSign::by_layout);
  ASSERT_EQ(r.t_s.size(), cycle.size());
  EXPECT_DOUBLE_EQ(r.voltage_v[5], 3.68);
  EXPECT_DOUBLE_EQ(r.current_a[5], -0.55);
  EXPECT_DOUBLE_EQ(r.current_a.back(), 1.1);
  EXPECT_EQ(r.step[5], 1);
  std::string text = biologic(cycle);
  const auto p = text.find("3,400000");
  text.replace(p, 8, "XXX");
  const fs::path bad = write("bad.mpt", text);
  EXPECT_EQ(error_of([&] { read_cycler_record({bad}, CurrentSign::by_layout); }),
            bad.string() + ": line 6, column 4 ('Ecell/V'): not a finite number: 'XXX'");
}

std::string nasa(const std::vector<Sample>& part, double t0) {
  std::string out = "Voltage_measured,Current_measured,Temperature_measured,Current_load,Voltage_load,Time\n";
  for (const Sample& s : part)
    out += fmt::format("{},{},24.5,{},{},{}\n", s.voltage_v, s.current_a, s.current_a, s.voltage_v, s.t_s - t0);
  return out;
}

TEST(CyclerFormats, NasaRecordsOrderedByTheirIndex) {
  const auto cycle = one_cycle(0.0, 10.0);
  const std::vector<Sample> charge(cycle.begin(), cycle.begin() + 17), discharge(cycle.begin() + 17, cycle.end());
  const fs::path dir = fs::path(::testing::TempDir()) / "cycler_formats" / "nasa";
  fs::create_directories(dir);
  std::ofstream(dir / "00002.csv") << nasa(discharge, discharge.front().t_s);
  std::ofstream(dir / "00001.csv") << nasa(charge, 0.0);
  std::ofstream(dir / "metadata.csv")
      << "type,start_time,ambient_temperature,battery_id,test_id,uid,filename,Capacity,Re,Rct\n"
         "discharge,[2010.  7.  21.  15.  2.  50.093],24,B0005,1,2,00002.csv,1.8,,\n"
         "charge,[2010.  7.  21.  15.  0.  0.0],24,B0005,0,1,00001.csv,,,\n";
  const CyclerRecord r = read_cycler_record({dir}, CurrentSign::by_layout);
  ASSERT_EQ(r.files.size(), 2u);
  EXPECT_EQ(fs::path(r.files.front()).filename(), "00001.csv");
  ASSERT_EQ(r.t_s.size(), cycle.size());
  EXPECT_NEAR(r.t_s[17], 170.093, 1e-6);
  EXPECT_DOUBLE_EQ(r.current_a[5], -0.55);
  EXPECT_DOUBLE_EQ(r.current_a.back(), 1.1);
  ASSERT_EQ(r.temperature_k.size(), cycle.size());
  EXPECT_NEAR(r.temperature_k.front(), 297.65, 1e-9);
  // Without its start time, a record cannot be ordered among others.
  const fs::path lone = fs::path(::testing::TempDir()) / "cycler_formats" / "nasa_noindex";
  fs::create_directories(lone);
  std::ofstream(lone / "00001.csv") << nasa(charge, 0.0);
  std::ofstream(lone / "00002.csv") << nasa(discharge, discharge.front().t_s);
  EXPECT_NE(error_of([&] { read_cycler_record({lone}, CurrentSign::by_layout); }).find("not in the index"),
            std::string::npos);
  std::string text = nasa(charge, 0.0);
  text.replace(text.find("3.64,"), 4, "3.6V");
  const fs::path bad = write("nasa_bad.csv", text);
  EXPECT_EQ(error_of([&] { read_cycler_record({bad}, CurrentSign::by_layout); }),
            bad.string() + ": line 6, column 1 ('Voltage_measured'): not a finite number: '3.6V'");
}

TEST(CyclerFormats, NotACyclerFileIsSaidSo) {
  const fs::path f = write("plain.csv", "a,b\n1,2\n");
  EXPECT_EQ(detect_cycler_layout_of(f).layout, CyclerLayout::none);
  EXPECT_NE(error_of([&] { read_cycler_record({f}, CurrentSign::by_layout); }).find("line 1: not a cycler time series"),
            std::string::npos);
}

TEST(CyclerFormats, CalceCs2FolderReadAsItComes) {
  const fs::path dir = BMS_SHARED_DIR "/data/calce-cs2-35";
  if (!fs::exists(dir)) GTEST_SKIP() << dir << " not present";
  const CyclerRecord r = read_cycler_record({dir}, CurrentSign::by_layout);
  EXPECT_EQ(r.layout, "Arbin");
  EXPECT_EQ(r.files.size(), 24u);
  EXPECT_GT(r.cycle.back(), 800);
  EXPECT_GT(r.gaps_under_current, 0u);
  for (std::size_t i = 1; i < r.t_s.size(); ++i) ASSERT_GT(r.t_s[i], r.t_s[i - 1]) << i;
  ASSERT_EQ(r.step_time_s.size(), r.t_s.size());  // Arbin's Step_Time(s) in every file
  for (double s : r.step_time_s) ASSERT_GE(s, 0.0);
}

// Cycler exports as real ones come, each read wrongly in silence or refused before these tests.

TEST(CyclerFormats, MaccorMagnitudeInAStepOfNoDirectionIsRefused) {
  // Maccor's "O" state (neither charge, discharge nor rest) with an unsigned current: its sign
  // was taken as discharge.
  std::string text = maccor(one_cycle(0.0, 10.0));
  const auto row = text.find("\n8\t");  // a charge row at 0.55 A, line 10
  ASSERT_NE(row, std::string::npos);
  text.replace(text.find("\tC\t", row), 3, "\tO\t");
  const fs::path f = write("other_state.001.txt", text);
  EXPECT_EQ(error_of([&] { read_cycler_record({f}, CurrentSign::by_layout); }),
            f.string() + ": line 10, column 8 ('Amps'): current 0.55 A logged as a magnitude in a step of no "
                         "direction ('O' in column 10): charge or discharge cannot be told");
}

TEST(CyclerFormats, MaccorRecHeaderWithDayClockTimes) {
  // Maccor's other text export: "Rec", "TestTime" as "Nd HH:MM:SS.ff", "Current [A]", "Md".
  std::string text = "Rec\tCycle P\tCycle C\tStep\tTestTime\tStepTime\tCap. [Ah]\tCurrent [A]\tVoltage [V]\tMd\tES\n";
  int rec = 1;
  for (const Sample& s : one_cycle(86340.0, 10.0)) {
    const int t = static_cast<int>(s.t_s);
    text += fmt::format("{}\t1\t1\t{}\t{}d {:02d}:{:02d}:{:02d}.00\t0d 00:00:00.00\t0\t{}\t{}\t{}\t0\n", rec++, s.step,
                        t / 86400, t / 3600 % 24, t / 60 % 60, t % 60, std::abs(s.current_a), s.voltage_v, s.state);
  }
  const fs::path f = write("rec_variant.txt", text);
  EXPECT_EQ(detect_cycler_layout_of(f).layout, CyclerLayout::maccor);
  const CyclerRecord r = read_cycler_record({f}, CurrentSign::by_layout);
  EXPECT_DOUBLE_EQ(r.t_s[7] - r.t_s[6], 10.0);  // across the day's end
  EXPECT_DOUBLE_EQ(r.current_a[5], -0.55);
  EXPECT_DOUBLE_EQ(r.current_a.back(), 1.1);
}

TEST(CyclerFormats, SemicolonsAndDecimalCommas) {
  // An Arbin CSV saved in a European locale: ';' between cells, ',' as the decimal mark.
  std::string text = arbin(one_cycle(30.0, 30.0), 1, 0.0);
  std::replace(text.begin(), text.end(), ',', ';');
  std::replace(text.begin(), text.end(), '.', ',');
  const fs::path f = write("arbin_semicolon.csv", text);
  const CyclerLayoutGuess g = detect_cycler_layout_of(f);
  EXPECT_EQ(g.layout, CyclerLayout::arbin);
  EXPECT_EQ(g.delimiter, ';');
  const CyclerRecord r = read_cycler_record({f}, CurrentSign::by_layout);
  EXPECT_DOUBLE_EQ(r.current_a[5], -0.55);
  EXPECT_DOUBLE_EQ(r.voltage_v[5], 3.68);
  EXPECT_DOUBLE_EQ(r.t_s[1] - r.t_s[0], 30.0);
}

TEST(CyclerFormats, ByteOrderMarkBeforeTheHeader) {
  // A NASA PCoE file saved with a UTF-8 BOM was not recognised (its first column name carried it).
  const auto cycle = one_cycle(0.0, 10.0);
  const fs::path f = write("nasa_bom.csv", "\xEF\xBB\xBF" + nasa(cycle, 0.0));
  EXPECT_EQ(detect_cycler_layout_of(f).layout, CyclerLayout::nasa);
  const CyclerRecord r = read_cycler_record({f}, CurrentSign::by_layout);
  EXPECT_DOUBLE_EQ(r.current_a[5], -0.55);
}

TEST(CyclerFormats, Latin1DegreeSignAndAnIndexColumn) {
  // A data set converted by pandas (an unnamed index column first) from a Windows export whose
  // temperature unit is a Latin-1 degree sign.
  std::string text;
  int row = -1;
  const std::string arbin_text = arbin(one_cycle(30.0, 30.0), 1, 0.0);
  for (std::size_t at = 0; at < arbin_text.size();) {
    const auto nl = arbin_text.find('\n', at);
    const std::string line = arbin_text.substr(at, nl - at);
    const std::string temperature = row < 0 ? ",Temperature (\xb0" "C)_1" : ",24.5";
    text += (row < 0 ? std::string() : std::to_string(row)) + "," + line + temperature + "\n";
    ++row;
    at = nl + 1;
  }
  const fs::path f = write("calce_pandas.csv", text);
  const CyclerRecord r = read_cycler_record({f}, CurrentSign::by_layout);
  ASSERT_EQ(r.temperature_k.size(), r.t_s.size());
  EXPECT_NEAR(r.temperature_k.front(), 297.65, 1e-9);
  EXPECT_DOUBLE_EQ(r.current_a[5], -0.55);
}

TEST(CyclerFormats, DotNetDaysInAClockTime) {
  // Windows cycler software writes a duration past a day as .NET's "D.HH:MM:SS": "1.00:00:30"
  // is a day and 30 s, not 1.0 h.
  double s = 0.0;
  ASSERT_TRUE(parse_duration_s("1.02:03:04", s));
  EXPECT_DOUBLE_EQ(s, 93784.0);
  ASSERT_TRUE(parse_duration_s("12:03:04.5", s));
  EXPECT_DOUBLE_EQ(s, 43384.5);
  EXPECT_FALSE(parse_duration_s("1.5:03", s));  // no clock has fractional minutes before its seconds
  std::string text = "Record ID,Total Time,Step ID,Cycle ID,Step Type,Current(A),Voltage(V)\n";
  int rec = 1;
  for (const Sample& x : one_cycle(86280.0, 30.0)) {
    const int t = static_cast<int>(x.t_s);
    const std::string clock = fmt::format("{:02d}:{:02d}:{:02d}", t / 3600 % 24, t / 60 % 60, t % 60);
    text += fmt::format("{},{},{},1,{},{},{}\n", rec++, t >= 86400 ? fmt::format("{}.{}", t / 86400, clock) : clock,
                        x.step, x.state == 'C' ? "CC_Chg" : x.state == 'D' ? "CC_DChg" : "Rest", x.current_a,
                        x.voltage_v);
  }
  const fs::path f = write("neware_days.csv", text);
  const CyclerRecord r = read_cycler_record({f}, CurrentSign::by_layout);
  for (std::size_t i = 1; i < r.t_s.size(); ++i) ASSERT_DOUBLE_EQ(r.t_s[i] - r.t_s[i - 1], 30.0) << i;
}

std::string neware_realtime(const std::vector<Sample>& cycle, bool day_first, int day, bool dotted = false) {
  std::string out = "Record ID,Realtime,Step ID,Cycle ID,Step Name,Current(A),Voltage(V)\n";
  int rec = 1;
  for (const Sample& s : cycle) {
    const int t = static_cast<int>(s.t_s) + 23 * 3600 + 50 * 60;  // from 23:50, over midnight
    const int d = day + t / 86400;
    out += fmt::format("{},{:02d}{}{:02d}{}2021 {:02d}:{:02d}:{:02d},{},1,{},{},{}\n", rec++, day_first ? d : 3,
                       dotted ? '.' : '/', day_first ? 3 : d, dotted ? '.' : '/', t / 3600 % 24, t / 60 % 60, t % 60,
                       s.step, s.state == 'C' ? "CC_Chg" : s.state == 'D' ? "CC_DChg" : "Rest", s.current_a,
                       s.voltage_v);
  }
  return out;
}

TEST(CyclerFormats, DayAndMonthTakenFromTheDatesOrRefused) {
  // Dates "04/03/2021" in a day-first locale were read as 3 April: midnight became a month.
  const auto cycle = one_cycle(0.0, 60.0);
  double s = 0.0, t = 0.0;
  ASSERT_TRUE(parse_date_time_s("04.03.2021 00:00:00", s));
  ASSERT_TRUE(parse_date_time_s("2021-03-04 00:00:00", t));
  EXPECT_EQ(s, t);
  for (const bool dotted : {true, false}) {
    // 12/03 -> 13/03: the 13 says day first.
    const CyclerRecord r =
        read_cycler_record({write("neware_dmy.csv", neware_realtime(cycle, true, 12, dotted))}, CurrentSign::by_layout);
    for (std::size_t i = 1; i < r.t_s.size(); ++i) ASSERT_DOUBLE_EQ(r.t_s[i] - r.t_s[i - 1], 60.0) << i;
  }
  const CyclerRecord us =
      read_cycler_record({write("neware_mdy.csv", neware_realtime(cycle, false, 12))}, CurrentSign::by_layout);
  for (std::size_t i = 1; i < us.t_s.size(); ++i) ASSERT_DOUBLE_EQ(us.t_s[i] - us.t_s[i - 1], 60.0) << i;
  // 04/03 -> 05/03: either reading is a date; the times differ by a month between them.
  const fs::path f = write("neware_ambiguous.csv", neware_realtime(cycle, true, 4));
  EXPECT_EQ(error_of([&] { read_cycler_record({f}, CurrentSign::by_layout); }),
            f.string() + ": line 2, column 2 ('Realtime'): dates A/B/YYYY where no day is over 12: day/month or "
                         "month/day cannot be told (write them as YYYY-MM-DD)");
}

TEST(CyclerFormats, CurrentSignAgainstTheStepTypesIsRefused) {
  // --current-sign overrode the step types' evidence (caught only if the voltage said so), and was
  // dropped without a word for a file of magnitudes.
  const auto cycle = one_cycle(0.0, 60.0);
  const fs::path n = write("neware_sign.csv", neware(cycle));
  EXPECT_EQ(error_of([&] { read_cycler_record({n}, CurrentSign::discharge_positive); }),
            n.string() + ": line 5, column 7 ('Current(mA)'): --current-sign discharge-positive contradicts the step "
                         "type ('CC_Chg' in column 6, current 550)");
  EXPECT_NO_THROW(read_cycler_record({n}, CurrentSign::charge_positive));
  const fs::path m = write("maccor_sign.001.txt", maccor(cycle));
  EXPECT_NE(read_cycler_record({m}, CurrentSign::discharge_positive).note.find("--current-sign not used"),
            std::string::npos);
}

TEST(CyclerFormats, ThousandsSeparatorBesideDecimalPointsIsRefused) {
  // A tab-separated export with '.' decimals and a thousands separator: "1,100" was read as 1.1.
  std::string text = maccor(one_cycle(0.0, 10.0));
  const auto row = text.find("\n25\t");  // a discharge row (1.1 A), line 27
  ASSERT_NE(row, std::string::npos);
  const auto amps = text.find("\t1.1\t", row);
  ASSERT_NE(amps, std::string::npos);
  text.replace(amps, 5, "\t1,100\t");
  const fs::path f = write("thousands.001.txt", text);
  const std::string e = error_of([&] { read_cycler_record({f}, CurrentSign::by_layout); });
  EXPECT_NE(e.find("line 27, column 8 ('Amps'): '1,100' after '"), std::string::npos) << e;
  EXPECT_NE(e.find("a decimal point and a decimal comma in one column"), std::string::npos) << e;
}

}  // namespace
}  // namespace bms
