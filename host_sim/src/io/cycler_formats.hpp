#pragma once
// Cycler exports read as they come: Arbin CSV (MITS Pro, e.g. CALCE's data), Maccor text,
// Neware CSV, BioLogic EC-Lab text (.mpt) and the NASA PCoE layout (one file per charge or
// discharge, with the records' start times in an index file). The layout is told by the
// header; columns are found by name, units read from the header, the current's sign set by the
// layout (checked against the step type where the file has one, and against the voltage's
// response always) or by --current-sign. Several files of one cell are joined in time order;
// a logging gap splits the record into segments (nothing is interpolated across it here);
// step and cycle indices are kept (cycles numbered on across files).
//
// Every refusal is an InputError naming the file, the line and the column.
#include <cmath>
#include <filesystem>
#include <string>
#include <string_view>
#include <vector>

#include "io/measured_profile.hpp"

namespace bms {

enum class CyclerLayout { none, arbin, arbin_statistics, maccor, neware, biologic, nasa, nasa_index };

std::string_view cycler_layout_name(CyclerLayout layout);

struct CyclerLayoutGuess {
  CyclerLayout layout = CyclerLayout::none;
  std::size_t header_line = 0;  // 0-based
  char delimiter = ',';
};

// From the start of a file (its first few kilobytes are enough).
CyclerLayoutGuess detect_cycler_layout(std::string_view head);
// Reads the first 64 KiB of the file; CyclerLayout::none for a file that is no cycler layout.
CyclerLayoutGuess detect_cycler_layout_of(const std::filesystem::path& file);

// The cycler's own per-cycle numbers (Arbin: Discharge_Capacity / Charge_Capacity, cumulative
// within a file, and Internal_Resistance): what the estimate is compared with.
struct CyclerCycleStat {
  int cycle;           // numbered on across files, as CyclerRecord::cycle
  double t_end_s;      // record time of the cycle's last sample
  double charge_ah;    // NaN where the file has no capacity column
  double discharge_ah;
  double internal_resistance_ohm;  // the cycle's last nonzero value; NaN if none
};

// One file, read.
struct CyclerFile {
  std::string name;
  CyclerLayout layout = CyclerLayout::none;
  double start_epoch_s = std::nan("");  // absolute time of t_s = 0 (seconds since 1970, read as UTC)
  std::string no_start_why;             // why a file with dates has no start time; empty otherwise
  std::vector<double> t_s, current_a, voltage_v, temperature_k;  // current positive = discharge
  std::vector<double> step_time_s;  // time since the cycler's step began (Step_Time); empty: not logged
  std::vector<int> cycle, step;
  std::vector<std::size_t> line;  // 1-based source line of each row
  std::vector<CyclerCycleStat> cycle_stats;  // cycles numbered as in the file
  std::string time_column, current_column;
  std::string sign_note;  // how the current's sign was settled
};

// `index`: the NASA layout's start times by file name (see read_cycler_record); may be empty.
CyclerFile parse_cycler_file(std::string text, const std::string& name, CurrentSign sign);

struct CyclerRecord {
  std::string layout;
  std::vector<std::string> files;  // in time order
  double start_epoch_s = std::nan("");
  std::vector<double> t_s, current_a, voltage_v, temperature_k;  // t_s from the first sample
  // Time since the cycler's step began, NaN in files that do not log it; empty when none does.
  std::vector<double> step_time_s;
  std::vector<int> cycle, step;
  std::vector<std::size_t> segment_starts;  // first row of each gap-free segment; [0] = 0
  std::vector<std::size_t> file_starts;     // first row of each file
  std::vector<CyclerCycleStat> cycle_stats; // cycle numbering of the record, t_end_s record time
  std::size_t gaps = 0, gaps_under_current = 0;
  double longest_gap_s = 0.0, longest_gap_under_current_s = 0.0;
  std::string note;  // one line: how the files were read
};

// A gap: a time step over kGapFactor times the file's median step (and over 1 s more than it).
constexpr double kCyclerGapFactor = 3.0;

// `paths`: files and folders (a folder: every file in it of a recognised time-series layout;
// Arbin statistics and info sheets, README and the like are skipped and named in the note). The
// NASA layout needs the index (a CSV with `filename` and `start_time` columns, found among the
// paths or as metadata.csv beside a file) when more than one file is read.
CyclerRecord read_cycler_record(const std::vector<std::filesystem::path>& paths, CurrentSign sign);

// The record as the generic measured profile (for commands that take one).
MeasuredProfile to_measured_profile(const CyclerRecord& record);

}  // namespace bms
