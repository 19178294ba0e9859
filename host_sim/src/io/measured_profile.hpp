#pragma once
// Measured or simulated current/voltage records used to drive and score the models.
// Two formats, told apart by the header:
//  - About:Energy `Time [s],I[A],U[V]` (+ optional `T [degC]` / `Temperature [K]`), current
//    negative on discharge: negated on input to our convention (positive = discharge);
//  - our truth.csv (`t_s,current_a,voltage_v,current_meas_a,voltage_meas_v,...`).
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

namespace bms {

struct MeasuredProfile {
  std::vector<double> t_s;
  std::vector<double> current_a;  // positive = discharge
  std::vector<double> voltage_v;
  std::vector<double> temperature_k;  // empty if the file has no temperature
  std::vector<std::string> mode;      // empty if the file has no mode column
  std::string source;
};

// Which truth.csv columns to read; About:Energy files have one set and ignore this.
enum class ProfileColumns {
  truth,     // current_a, voltage_v
  measured,  // current_meas_a, voltage_meas_v (what the estimator may see)
};

// Throws InputError naming the file, line and column: missing column, empty or non-finite
// cell, fewer than 2 rows, time not strictly increasing, a gap (a step over 10x the median
// step and over 60 s), voltage outside 0..10 V, temperature outside -100..200 degC (catches
// a Celsius column labelled as kelvin), unknown mode.
MeasuredProfile read_measured_profile(const std::filesystem::path& file, ProfileColumns which);
MeasuredProfile parse_measured_profile(std::string_view text, std::string_view name,
                                       ProfileColumns which);

}  // namespace bms
