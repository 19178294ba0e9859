#include "sim/truth_output.hpp"

#include "io/atomic_file.hpp"
#include "io/child_process.hpp"
#include "io/csv_table.hpp"
#include "io/input_error.hpp"

namespace bms {

void write_file_atomically(const std::filesystem::path& file, const std::string& text) {
  AtomicFileWriter out(file);
  out.append(text);
  out.commit();
}

namespace {

const std::vector<std::string>& truth_columns() {
  static const std::vector<std::string> columns = {
      "t_s",           "cycle",      "mode",          "current_a", "voltage_v",  "current_meas_a", "voltage_meas_v",
      "r_film_ohm_m2", "j_s_a_m3",   "li_loss_ah",    "temperature_k", "charge_ah", "stoich_neg", "stoich_pos",
      "temperature_meas_k", "capacity_ah"};
  return columns;
}

void write_row(CsvWriter& w, const SampleRecord& s, const MeasuredSample& m) {
  w.cell(s.t_s).cell(s.cycle).cell(mode_name(s.mode)).cell(s.current_a).cell(s.voltage_v)
      .cell(m.current_a).cell(m.voltage_v).cell(s.r_film_ohm_m2).cell(s.j_s_a_m3)
      .cell(s.li_loss_ah).cell(s.temperature_k).cell(s.charge_ah).cell(s.stoich_neg).cell(s.stoich_pos)
      .cell(m.temperature_k).cell(s.capacity_ah);
  w.end_row();
}

}  // namespace

void write_truth_csv(const std::filesystem::path& file, const SimulationResult& r, const Measured& m) {
  CsvWriter w(file, truth_columns());
  for (size_t i = 0; i < r.samples.size(); ++i) write_row(w, r.samples[i], {m.current_a[i], m.voltage_v[i], m.temperature_k[i]});
  w.commit();
}

TruthCsvStream::TruthCsvStream(const std::filesystem::path& file, const MeasurementModel& sensor)
    : csv_(file, truth_columns()), sensor_(sensor) {}

void TruthCsvStream::on_sample(const SampleRecord& s) {
  throw_if_interrupted();
  const MeasuredSample m = sensor_.next(s);
  write_row(csv_, s, m);
  last_ = s;
  ++samples_;
}

nlohmann::json summary_json(const SimulationResult& r) {
  nlohmann::json j;
  j["cycles"] = nlohmann::json::array();
  for (const auto& c : r.cycles) {
    nlohmann::json cj{{"cycle", c.cycle},
                      {"r_film_start_ohm_m2", c.r_film_start_ohm_m2},
                      {"r_film_end_ohm_m2", c.r_film_end_ohm_m2},
                      {"growth_pct", c.growth_pct},
                      {"li_loss_ah", c.li_loss_ah}};
    nlohmann::json by_mode;
    for (Mode m : {Mode::rest, Mode::cc_discharge, Mode::cv_discharge, Mode::cc_charge, Mode::cv_charge}) {
      const auto i = static_cast<int>(m);
      by_mode[mode_name(m)] = {{"duration_s", c.duration_by_mode_s[i]},
                               {"film_growth_ohm_m2", c.growth_by_mode_ohm_m2[i]}};
    }
    cj["modes"] = by_mode;
    j["cycles"].push_back(cj);
  }
  j["sim_s"] = r.sim_s;
  j["wall_s"] = r.wall_s;
  j["samples"] = r.samples.size();
  j["solver"] = {{"steps", r.stats.steps},
                 {"residual_evals", r.stats.residual_evals},
                 {"jacobian_evals", r.stats.jacobian_evals},
                 {"reinits", r.stats.reinits},
                 {"jacobian_colors", r.stats.colors},
                 {"jacobian_nonzeros", r.stats.nonzeros}};
  if (!r.note.empty()) j["note"] = r.note;
  return j;
}

}  // namespace bms
