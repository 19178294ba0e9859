#include "io/measured_profile.hpp"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "io/input_error.hpp"

namespace bms {
namespace {

const std::string kDataDir = BMS_SHARED_DIR "/data/aboutenergy-lfp18650/";

std::string profile_error(const std::string& text,
                          ProfileColumns which = ProfileColumns::measured) {
  try {
    parse_measured_profile(text, "p.csv", which);
  } catch (const InputError& e) {
    return e.what();
  }
  return "(no error)";
}

TEST(MeasuredProfile, ReadsTheAboutEnergyFilesWithOurSignConvention) {
  struct Case {
    const char* file;
    std::size_t rows;
    double current_a;
  };
  for (const Case& c :
       {Case{"LFP_25degC_Co20.csv", 7454, 0.1}, Case{"LFP_25degC_1C.csv", 3500, 2.0},
        Case{"LFP_25degC_2C.csv", 1707, 4.0}}) {
    const MeasuredProfile p = read_measured_profile(kDataDir + c.file, ProfileColumns::measured);
    EXPECT_EQ(p.source, kDataDir + c.file);
    ASSERT_EQ(p.t_s.size(), c.rows) << c.file;
    EXPECT_EQ(p.current_a.size(), c.rows);
    EXPECT_EQ(p.voltage_v.size(), c.rows);
    EXPECT_TRUE(p.temperature_k.empty());
    EXPECT_TRUE(p.mode.empty());
    EXPECT_EQ(p.t_s.front(), 0.0);
    EXPECT_NEAR(p.voltage_v.back(), 1.999730087, 1e-12);
    // Discharge is positive in our convention: the file's "-2.0" is +2.0 here.
    EXPECT_NEAR(*std::max_element(p.current_a.begin(), p.current_a.end()), c.current_a,
                0.02 * c.current_a);
    EXPECT_GT(*std::min_element(p.current_a.begin(), p.current_a.end()), 0.0);
  }
  const MeasuredProfile one_c =
      read_measured_profile(kDataDir + "LFP_25degC_1C.csv", ProfileColumns::truth);
  const auto full = std::find_if(one_c.current_a.begin(), one_c.current_a.end(),
                                 [](double i) { return std::fabs(i) > 1.95; });
  ASSERT_NE(full, one_c.current_a.end());
  EXPECT_NEAR(*full, 2.0, 1e-3);
  EXPECT_EQ(full - one_c.current_a.begin(), 2);  // line 4 of the file: t = 1 s
  EXPECT_NEAR(one_c.current_a[0], 0.001955032, 1e-12);
}

TEST(MeasuredProfile, ReadsTruthCsvSelectingColumns) {
  const std::string file = BMS_SOURCE_DIR "/tests/io/data/truth_small.csv";
  const MeasuredProfile truth = read_measured_profile(file, ProfileColumns::truth);
  const MeasuredProfile meas = read_measured_profile(file, ProfileColumns::measured);
  EXPECT_EQ(truth.t_s, (std::vector<double>{0.0, 0.2, 0.4}));
  EXPECT_EQ(truth.current_a, (std::vector<double>{0.0, -2.5, -2.5}));  // already our sign
  EXPECT_EQ(truth.voltage_v, (std::vector<double>{3.4, 3.5, 3.51}));
  EXPECT_EQ(meas.current_a, (std::vector<double>{0.001, -2.499, -2.502}));
  EXPECT_EQ(meas.voltage_v, (std::vector<double>{3.4005, 3.5012, 3.5098}));
  EXPECT_EQ(meas.temperature_k, (std::vector<double>{298.15, 298.16, 298.17}));
  EXPECT_EQ(meas.mode, (std::vector<std::string>{"rest", "cc_charge", "cc_charge"}));
}

TEST(MeasuredProfile, AboutEnergyTemperatureColumns) {
  const MeasuredProfile c =
      parse_measured_profile("Time [s],I [A],U [V],T [degC]\n0,-1,3.3,25\n1,-1,3.2,26.5\n", "c.csv",
                             ProfileColumns::measured);
  EXPECT_EQ(c.current_a, (std::vector<double>{1.0, 1.0}));
  EXPECT_NEAR(c.temperature_k[1], 299.65, 1e-12);
  const MeasuredProfile k =
      parse_measured_profile("Time [s],I[A],U[V],Temperature [K]\n0,1,3.3,300\n1,1,3.2,301\n",
                             "k.csv", ProfileColumns::measured);
  EXPECT_EQ(k.current_a, (std::vector<double>{-1.0, -1.0}));  // charging
  EXPECT_EQ(k.temperature_k, (std::vector<double>{300.0, 301.0}));
  EXPECT_EQ(profile_error("Time [s],I[A],U[V],T [degC]\n0,1,3.3,25\n1,1,3.2,298\n"),
            "p.csv: line 3, column 4 ('T [degC]'): temperature 298 degC outside -100..200 degC");
  EXPECT_EQ(
      profile_error("t_s,current_meas_a,voltage_meas_v,temperature_k\n0,1,3.3,298\n1,1,3.2,25\n"),
      "p.csv: line 3, column 4 ('temperature_k'): temperature 25 K outside 173.15..473.15 K");
}

TEST(MeasuredProfile, ColumnsPickedByNameWithUnitsAndSign) {
  // A cycler export: other column order, extra columns, mA and minutes, charge-positive.
  const MeasuredProfile p = parse_measured_profile(
      "Step,Test_Time (min),Voltage(V),Current(mA),Temperature (degC)\n1,0,3.30,-1000,25\n1,0.5,3.29,-1000,25.5\n",
      "c.csv", ProfileColumns::measured);
  EXPECT_EQ(p.layout, "by column names");
  EXPECT_EQ(p.t_s, (std::vector<double>{0.0, 30.0}));
  EXPECT_EQ(p.current_a, (std::vector<double>{1.0, 1.0}));  // discharge-positive inside
  EXPECT_EQ(p.voltage_v, (std::vector<double>{3.30, 3.29}));
  EXPECT_NEAR(p.temperature_k[1], 298.65, 1e-12);
  const MeasuredProfile q = parse_measured_profile("time,current,voltage\n0,1,3\n1,1,3\n", "d.csv",
                                                   ProfileColumns::measured, CurrentSign::discharge_positive);
  EXPECT_EQ(q.current_a, (std::vector<double>{1.0, 1.0}));
  const MeasuredProfile ae = parse_measured_profile("Time [s],I[A],U[V]\n0,-1,3.3\n1,-1,3.2\n", "a.csv",
                                                    ProfileColumns::measured, CurrentSign::discharge_positive);
  EXPECT_EQ(ae.current_a, (std::vector<double>{-1.0, -1.0}));  // told otherwise: taken as given
  EXPECT_NE(profile_error("time,current,I [A],voltage\n0,1,1,3\n1,1,1,3\n").find("several current columns"),
            std::string::npos);
}

TEST(MeasuredProfile, BadFilesNameLineAndColumn) {
  const std::string ae = "Time [s],I[A],U[V]\n";
  EXPECT_EQ(profile_error(ae + "0,-1,3.3\n1,-1,3.2\n0.5,-1,3.1\n"),
            "p.csv: line 4, column 1 ('Time [s]'): time 0.5 s goes back from the previous row's "
            "1 s (time must strictly increase)");
  EXPECT_EQ(profile_error(ae + "0,-1,3.3\n1,-1,3.2\n1,-1,3.1\n"),
            "p.csv: line 4, column 1 ('Time [s]'): time 1 s repeats the previous row's 1 s (time "
            "must strictly increase)");
  EXPECT_EQ(profile_error(ae + "0,-1,3.3\n1,NaN,3.2\n"),
            "p.csv: line 3, column 2 ('I[A]'): not a finite number: 'NaN'");
  EXPECT_EQ(profile_error(ae + "0,-1,3.3\n1,,3.2\n"),
            "p.csv: line 3, column 2 ('I[A]'): empty cell");
  EXPECT_EQ(profile_error("Time [s],I[A]\n0,-1\n1,-1\n"),
            "p.csv: line 1: missing column 'U[V]' (the header has: Time [s], I[A])");
  EXPECT_EQ(profile_error(ae + "0,-1,3.3\n"), "p.csv: needs at least 2 data rows, has 1");
  EXPECT_EQ(profile_error(ae + "0,-1,3.3\n1,-1,12.5\n"),
            "p.csv: line 3, column 3 ('U[V]'): voltage 12.5 V outside 0..10 V");
  EXPECT_EQ(profile_error(ae + "0,-1,3.3\n1,-1,-0.1\n"),
            "p.csv: line 3, column 3 ('U[V]'): voltage -0.1 V outside 0..10 V");
  EXPECT_EQ(profile_error("time,current\n0,1\n1,1\n"),
            "p.csv: line 1: no voltage column (the header has: time, current); name it e.g. 'Voltage [V]'");
  EXPECT_EQ(profile_error("Time [s],Voltage [V]\n0,3\n1,3\n"),
            "p.csv: line 1: no current column (the header has: Time [s], Voltage [V]); name it e.g. 'Current [A]'");
  EXPECT_EQ(profile_error("Current [A],Voltage [V]\n1,3\n1,3\n"),
            "p.csv: line 1: no time column (the header has: Current [A], Voltage [V]); name it e.g. 'Time [s]'");

  std::string gap = ae;
  for (int t = 0; t < 20; ++t) gap += std::to_string(t) + ",-1,3.3\n";
  gap += "3600,-1,3.2\n3601,-1,3.2\n";
  EXPECT_EQ(profile_error(gap),
            "p.csv: line 22, column 1 ('Time [s]'): gap of 3581 s in the record after t = 19 s "
            "(line 21) under current; the median time step is 1 s (a gap is accepted only at rest)");
  // The same gap at rest on both sides: a logger that paused during a long rest.
  std::string rest_gap = ae;
  for (int t = 0; t < 20; ++t) rest_gap += std::to_string(t) + (t < 10 ? ",-1,3.3\n" : ",0,3.3\n");
  rest_gap += "3600,0,3.31\n3601,-1,3.2\n";
  EXPECT_EQ(profile_error(rest_gap), "(no error)");
  // A long step is fine when the record is sampled that slowly anyway, or when it is short.
  EXPECT_EQ(profile_error(ae + "0,-1,3.3\n100,-1,3.2\n200,-1,3.2\n400,-1,3.2\n"), "(no error)");
  EXPECT_EQ(profile_error(ae + "0,-1,3.3\n0.1,-1,3.2\n0.2,-1,3.2\n50,-1,3.2\n"), "(no error)");

  const std::string truth = "t_s,mode,current_a,voltage_v,current_meas_a,voltage_meas_v\n";
  EXPECT_EQ(
      profile_error(truth + "0,rest,0,3.3,0,3.3\n1,rest,0,3.3,0,3.3\n", ProfileColumns::truth),
      "(no error)");
  EXPECT_EQ(profile_error(truth + "0,rest,0,3.3,0,3.3\n1,resting,0,3.3,0,3.3\n"),
            "p.csv: line 3, column 2 ('mode'): unknown mode 'resting' (expected one of rest, "
            "cc_discharge, cv_discharge, cc_charge, cv_charge)");
  EXPECT_EQ(profile_error("t_s,current_a,voltage_v\n0,0,3.3\n1,0,3.3\n"),
            "p.csv: line 1: missing column 'current_meas_a' (the header has: t_s, current_a, "
            "voltage_v)");
  EXPECT_THROW(read_measured_profile(kDataDir + "missing.csv", ProfileColumns::truth), InputError);
}

// A temperature in degF is converted, never read as degC; a unit it does not know is refused.
TEST(MeasuredProfile, FahrenheitConvertedUnknownTemperatureUnitRefused) {
  const MeasuredProfile p = parse_measured_profile(
      "Time [s],Current [A],Voltage [V],Temperature [degF]\n0,0,3.3,77\n1,0,3.3,32\n", "f.csv", ProfileColumns::measured);
  ASSERT_EQ(p.temperature_k.size(), 2u);
  EXPECT_NEAR(p.temperature_k[0], 298.15, 1e-9);
  EXPECT_NEAR(p.temperature_k[1], 273.15, 1e-9);
  EXPECT_EQ(profile_error("Time [s],Current [A],Voltage [V],Temperature [degR]\n0,0,3.3,500\n1,0,3.3,500\n"),
            "p.csv: line 1: column 'Temperature [degR]': temperature unit 'degr' not understood (K, degC or degF)");
}

// The current's sign against the voltage's response: discharge-positive data under a cycler
// header (read charge-positive) are refused naming the option; the option reads them.
TEST(MeasuredProfile, SignContradictingTheVoltageRefused) {
  const std::string text =
      "Time [s],Current [A],Voltage [V]\n0,0,3.30\n1,2,3.20\n2,0,3.29\n3,2,3.19\n4,0,3.28\n5,2,3.18\n";
  const std::string e = profile_error(text);
  EXPECT_NE(e.find("p.csv: the current read as charge-positive contradicts the voltage"), std::string::npos) << e;
  EXPECT_NE(e.find("give --current-sign discharge-positive"), std::string::npos) << e;
  const MeasuredProfile p =
      parse_measured_profile(text, "p.csv", ProfileColumns::measured, CurrentSign::discharge_positive);
  EXPECT_DOUBLE_EQ(p.current_a[1], 2.0);
}

// simulate --protocol csv: and diagnose read a cycler's export by its layout, as estimate does:
// a Maccor text file (a metadata line before the header, |I| with the direction in 'State') was
// refused as having no time column.
TEST(MeasuredProfile, CyclerExportReadByItsLayout) {
  std::string text = "Today's Date\t03/05/2021\tDate of Test:\t03/04/2021\n"
                     "Rec#\tCyc#\tStep\tTest (Sec)\tStep (Sec)\tAmp-hr\tWatt-hr\tAmps\tVolts\tState\tES\tDPt Time\n";
  const auto row = [&](int rec, double t, double amps, double volts, char state) {
    text += std::to_string(rec) + "\t0\t1\t" + std::to_string(t) + "\t0\t0\t0\t" + std::to_string(amps) + "\t" +
            std::to_string(volts) + "\t" + state + "\t0\t03/04/2021 2:00:00 PM\n";
  };
  int rec = 1;
  double t = 0.0;
  for (int k = 0; k < 20; ++k, t += 2.0) row(rec++, t, 1.0, 3.30 - 0.002 * k, 'D');
  for (int k = 0; k < 20; ++k, t += 2.0) row(rec++, t, 1.0, 3.35 + 0.002 * k, 'C');
  const auto file = std::filesystem::path(::testing::TempDir()) / "maccor_profile.txt";
  std::ofstream(file) << text;
  const MeasuredProfile p = read_measured_profile(file, ProfileColumns::truth);
  ASSERT_EQ(p.t_s.size(), 40u);
  EXPECT_EQ(p.layout, "Maccor");
  EXPECT_DOUBLE_EQ(p.current_a.front(), 1.0);  // discharge positive
  EXPECT_DOUBLE_EQ(p.current_a.back(), -1.0);
  // A logging gap under current: refused here (the model would be driven across it).
  row(rec++, t + 600.0, 1.0, 3.40, 'C');
  std::ofstream(file) << text;
  try {
    read_measured_profile(file, ProfileColumns::truth);
    ADD_FAILURE() << "no error";
  } catch (const InputError& e) {
    EXPECT_NE(std::string(e.what()).find(file.string() + ": line 43, column 'Test (Sec)': gap of 602 s"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace bms
