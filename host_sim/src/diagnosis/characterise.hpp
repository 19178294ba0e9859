#pragma once
// Where the residual lives: by operating mode, state of charge, current and rate of change
// of the voltage, plus a linear signature fit that points at candidate effects.
#include <string>
#include <vector>

#include "diagnosis/records.hpp"

namespace bms::diagnosis {

struct ResidualGroup {
  std::string dimension;  // "mode", "soc", "current", "since_step", "dvdt"
  std::string label;      // e.g. "cc_charge", "0.2-0.3", "-2.5..-1.2 A"
  std::size_t samples = 0;
  double mean_mv = 0.0, rms_mv = 0.0;
};

// residual ~ c + r_apparent * I + h_apparent * sign(I) over the samples with current: a
// contact resistance shows as r_apparent, hysteresis as h_apparent (both positive for an
// effect the model lacks, since residual = model - measured).
struct ResidualSignature {
  double offset_mv = 0.0;
  double r_apparent_mohm = 0.0;
  double h_apparent_mv = 0.0;
  bool valid = false;  // false when the record cannot separate the three terms
};

struct Characterisation {
  std::vector<ResidualGroup> groups;
  ResidualSignature signature;
};

Characterisation characterise(const Record& r, const std::vector<double>& residual_mv,
                              const std::vector<double>& soc);

}  // namespace bms::diagnosis
