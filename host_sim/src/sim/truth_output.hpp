#pragma once
// Writes a simulation's truth.csv and summary.json (contract: simulate).
#include <filesystem>
#include <string>

#include <nlohmann/json.hpp>

#include "io/csv_table.hpp"
#include "sim/cycler.hpp"
#include "sim/measurement.hpp"

namespace bms {

// Writes text to FILE.tmp and renames it, so a reader never sees a partial file.
void write_file_atomically(const std::filesystem::path& file, const std::string& text);

void write_truth_csv(const std::filesystem::path& file, const SimulationResult& r, const Measured& m);

// truth.csv written as the truth model produces it: each sample is measured and written at
// once, so memory does not grow with the run. Keeps the cycle summaries and the first and last
// samples for summary.json; commit() renames truth.csv into place (also after a failure, when
// the summary says the run is incomplete).
class TruthCsvStream : public SampleSink {
 public:
  TruthCsvStream(const std::filesystem::path& file, const MeasurementModel& sensor);
  void on_sample(const SampleRecord& s) override;
  void on_cycle(const CycleSummary& c) override { cycles_.push_back(c); }
  void commit() { csv_.commit(); }

  long samples() const { return samples_; }
  const std::vector<CycleSummary>& cycles() const { return cycles_; }
  const SampleRecord& last() const { return last_; }

 private:
  CsvWriter csv_;
  Measurer sensor_;
  std::vector<CycleSummary> cycles_;
  SampleRecord last_{};
  long samples_ = 0;
};

nlohmann::json summary_json(const SimulationResult& r);

}  // namespace bms
