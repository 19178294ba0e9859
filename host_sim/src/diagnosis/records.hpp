#pragma once
// Measured records for the diagnosis: the current that drives the model, the voltage it is
// scored against, and what the record can and cannot tell apart (its excitation).
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "io/measured_profile.hpp"
#include "sim/cycler.hpp"

namespace bms::diagnosis {

struct Record {
  std::string source;
  std::vector<double> t_s;
  std::vector<double> current_a;      // measured, positive = discharge
  std::vector<double> voltage_v;      // measured terminal voltage
  std::vector<double> temperature_k;  // empty when the file has none
  std::vector<Mode> mode;             // from the file's mode column, else from the current
  // Charge taken from the cell's default initial state before the first sample (NaN: start
  // in the default state); set by set_initial_state.
  double initial_depth_ah = std::numeric_limits<double>::quiet_NaN();
  std::string initial_state_note;
  std::string layout_note;  // how the file's columns and current sign were read
  double duration_s() const { return t_s.back() - t_s.front(); }
};

// Below these a record holds too little to fit and validate anything.
inline constexpr std::size_t kMinSamples = 50;
inline constexpr double kMinDurationS = 60.0;

// Reads the About:Energy or truth.csv format (measured columns only; never the truth ones).
// Throws InputError naming the file for unreadable, non-monotonic, gappy, NaN or too short
// records.
Record load_record(const std::filesystem::path& file, CurrentSign sign = CurrentSign::by_layout);
// The same checks on a record already in memory (name = what errors call it).
Record make_record(std::string name, std::vector<double> t_s, std::vector<double> current_a,
                   std::vector<double> voltage_v, std::vector<double> temperature_k = {},
                   std::vector<Mode> mode = {});

// What the current does over the record. With one constant current only, effects whose
// residual is proportional to the current or constant (contact resistance and hysteresis;
// sensor offset and gain) give the same signature and cannot be told apart.
struct Excitation {
  double max_abs_current_a = 0.0;
  double typical_current_a = 0.0;  // median of the non-rest current
  double rest_fraction = 0.0;      // share of samples at rest
  bool has_discharge = false, has_charge = false, has_cv = false;
  int current_levels = 0;          // distinct CC levels (2 % of max |I| apart)
  bool no_current = false;         // rest only: nothing to diagnose
  bool constant_current_only = false;
  std::string describe() const;
};

Excitation analyse_excitation(const Record& r);

// Seconds since the last step of the current (a change over 5 % of the largest current
// between two samples), or since the start.
std::vector<double> time_since_step_s(const Record& r);

// State of charge by coulomb counting from the cell's initial state (for characterisation).
std::vector<double> state_of_charge(const Record& r, double soc0, double capacity_ah);

}  // namespace bms::diagnosis
