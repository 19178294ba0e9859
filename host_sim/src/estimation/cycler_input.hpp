#pragma once
// What `estimate` reads: one truth.csv or measured CSV (read_estimate_data), or a cycler's
// exports (cycler_formats.hpp: one file, several, or a folder of one cell's files, joined in time
// order), with the cycler's own per-cycle capacity and resistance kept for the comparison.
#include <string>
#include <vector>

#include "estimation/estimate_run.hpp"
#include "io/cycler_formats.hpp"

namespace bms {

struct EstimateInput {
  EstimateData data;
  bool from_cycler = false;
  std::vector<CyclerCycleStat> cycler_cycles;  // empty unless the layout carries them (Arbin)
  std::string label;                           // the --data values, for messages
};

EstimateInput read_estimate_input(const std::vector<std::string>& paths, CurrentSign sign);

}  // namespace bms
