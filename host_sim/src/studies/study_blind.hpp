#pragma once
// `bmssim study blind`: the estimator on truths it does not know. Each case draws a
// truth (seeded, uniform) from ranges the estimator never sees, simulates it with one noise
// condition, and runs every estimator arm on the measured columns only: the best profile, each
// of its features switched off, learning off (the control), the paper's RCSI and the
// nominal-growth profile. Beside them: the Cramer-Rao bound of the joint unknowns for the same data.
#include <string>
#include <vector>

namespace bms::study {

struct BlindStudyOptions {
  int seeds = 10;
  int cycles = 5;
  int jobs = 2;
  // 1: film, growth law, side i0, inventory; 2: + conductivity, diffusivities; 3: set 1 at 5-45 C;
  // 4: set 1 + cell-to-cell spread; 5: set 1 + a BMS front end's sensors; 6: set 1 + drawn protocols.
  std::string sets = "1,2";
  std::vector<std::string> arms;  // only these arms (empty: all)
  bool list_cases = false;        // print each case's truth command and run nothing
  std::string out;
  bool quiet = false;
  std::string cell = "paper";  // paper | aboutenergy | lco | nmc | FILE.bpx.json
  int truth_points = 20;       // the truths' DFN mesh: volumes per region and per particle
  double truth_rtol = 1e-6;    // the truths' solver tolerance
};

// Runs (or resumes: finished cases are kept) the study and writes OUT/summary.json, report.md
// and figures/. Returns the number of cases whose truth could not be simulated.
int run_blind_study(const BlindStudyOptions& o, const std::string& command);

}  // namespace bms::study
