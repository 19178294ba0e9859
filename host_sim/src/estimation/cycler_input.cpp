#include "estimation/cycler_input.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <filesystem>

#include "io/input_error.hpp"

namespace bms {

namespace {

// As for any measured file (read_estimate_data): the record's median step, refused above
// kMaxSampleStepS; the model tick at most kMaxModelTickS and a whole fraction of that step.
void set_sample_clock(EstimateData& d, const std::string& label) {
  if (d.t_s.size() < 2) throw InputError(label + ": needs at least 2 samples");
  std::vector<double> dt(d.t_s.size() - 1);
  for (std::size_t i = 1; i < d.t_s.size(); ++i) dt[i - 1] = d.t_s[i] - d.t_s[i - 1];
  std::nth_element(dt.begin(), dt.begin() + static_cast<long>(dt.size() / 2), dt.end());
  const double step = dt[dt.size() / 2];
  if (step > kMaxControlSampleStepS)
    throw InputError(fmt::format("{}: sampled every {} s (the median step); the estimator needs a sample at least "
                                 "every {} s during a charge",
                                 label, step, kMaxSampleStepS));
  d.median_step_s = step;
  d.tick_s = std::round(step / std::ceil(step / kMaxModelTickS - 1e-9) * 1e9) / 1e9;
  d.layout_note += fmt::format("; median step {} s, model tick {} s (the ticks between samples and over gaps are "
                               "caught up as the firmware catches up missed ticks)",
                               step, d.tick_s);
}

}  // namespace

EstimateInput read_estimate_input(const std::vector<std::string>& paths, CurrentSign sign) {
  EstimateInput in;
  if (paths.empty()) throw InputError("--data: give a file or a folder");
  in.label = fmt::format("{}", fmt::join(paths, ", "));
  std::error_code ec;
  if (paths.size() == 1 && !std::filesystem::is_directory(paths.front(), ec) &&
      detect_cycler_layout_of(paths.front()).layout == CyclerLayout::none) {
    in.data = read_estimate_data(paths.front(), sign);
    return in;
  }
  std::vector<std::filesystem::path> p(paths.begin(), paths.end());
  CyclerRecord rec = read_cycler_record(p, sign);
  in.from_cycler = true;
  in.cycler_cycles = std::move(rec.cycle_stats);
  EstimateData& d = in.data;
  d.source = in.label;
  d.layout_note = rec.note;
  d.t_s = std::move(rec.t_s);
  d.current_a = std::move(rec.current_a);
  d.voltage_v = std::move(rec.voltage_v);
  d.cycle = std::move(rec.cycle);
  d.step_time_s = std::move(rec.step_time_s);
  set_sample_clock(d, in.label);
  return in;
}

}  // namespace bms
