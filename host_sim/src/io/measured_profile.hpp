#pragma once
// Measured or simulated current/voltage records used to drive and score the models.
// Three layouts, told apart by the header:
//  - our truth.csv (`t_s,current_a,voltage_v,current_meas_a,voltage_meas_v,...`);
//  - About:Energy `Time [s],I[A],U[V]` (+ optional `T [degC]` / `Temperature [K]`), current
//    negative on discharge: negated on input to our convention (positive = discharge);
//  - a cycler export of a known layout (Arbin, Maccor, Neware, BioLogic, NASA PCoE; read by
//    read_measured_profile as cycler_formats.hpp reads it, a gap under current refused);
//  - any other CSV: columns picked by name (time, current, voltage, temperature;
//    units s/min/h, A/mA, V/mV, degC/K read from the name), current charge-positive unless
//    told otherwise.
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
  std::string layout;  // "truth.csv", "About:Energy" or "by column names"
  bool current_negated = false;  // the file's current was charge-positive
};

// Which truth.csv columns to read; About:Energy files have one set and ignore this.
enum class ProfileColumns {
  truth,     // current_a, voltage_v
  measured,  // current_meas_a, voltage_meas_v (what the estimator may see)
};

// The sign of the file's current column: as its layout says (truth.csv: discharge-positive;
// About:Energy and other cycler exports: charge-positive), or as given.
enum class CurrentSign { by_layout, discharge_positive, charge_positive };

// Throws InputError naming the file, line and column: missing column, empty or non-finite
// cell, fewer than 2 rows, time not strictly increasing, a gap under current (a step over 10x
// the median step and over 60 s; accepted when the cell rests on both sides), voltage outside 0..10 V, temperature outside -100..200 degC (catches
// a Celsius column labelled as kelvin), unknown mode.
MeasuredProfile read_measured_profile(const std::filesystem::path& file, ProfileColumns which,
                                      CurrentSign sign = CurrentSign::by_layout);
MeasuredProfile parse_measured_profile(std::string_view text, std::string_view name,
                                       ProfileColumns which, CurrentSign sign = CurrentSign::by_layout);
// "discharge-positive" / "charge-positive"; false for anything else.
bool parse_current_sign(std::string_view text, CurrentSign& out);
// The --current-sign option of the commands that read measured files: "" or "by-layout" is
// CurrentSign::by_layout; anything but the two names is an InputError naming the option.
CurrentSign current_sign_option(std::string_view text);

}  // namespace bms
