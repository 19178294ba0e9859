#include "estimation/charges.hpp"

#include <algorithm>
#include <cmath>

#include "bms/fw/estimation/operating_mode.hpp"

namespace bms {

namespace {

constexpr double kRestShare = 0.01;          // |I| below this share of the largest |I|: rest
constexpr double kGapFactor = 3.0;           // a step over this many median steps: a logging gap
constexpr double kLongRestS = 3600.0;        // a rest this long ends a charge
constexpr double kSensorGainSd = 1e-3;       // the current sensor's relative gain uncertainty (1 sigma)

double median_step(const std::vector<double>& t) {
  std::vector<double> d;
  d.reserve(t.size());
  for (std::size_t i = 1; i < t.size(); ++i) d.push_back(t[i] - t[i - 1]);
  if (d.empty()) return 0.0;
  std::nth_element(d.begin(), d.begin() + static_cast<long>(d.size() / 2), d.end());
  return d[d.size() / 2];
}

struct Counted {
  double ah = 0.0, gap_ah = 0.0, r_step_ohm = std::nan(""), r_discharge_step_ohm = std::nan("");
  double r_discharge_onset_ohm = std::nan("");
  bool ended = false;         // at a discharge or a long rest: not cut by a power cycle or the record's end
  bool started_empty = false;  // the last discharge before it reached the cell's lower voltage limit
};

constexpr double kEmptyBandV = 0.05;  // a discharge that ended this close to the lower limit emptied the cell

// Whether the discharge before sample k (skipping the rest between) ended at the lower limit.
bool discharged_to_limit(const EstimateData& d, std::size_t k, double rest_a, double lower_v) {
  while (k > 0 && std::abs(d.current_a[k - 1]) <= rest_a) --k;
  return k > 0 && d.current_a[k - 1] > rest_a && d.voltage_v[k - 1] <= lower_v + kEmptyBandV;
}

// The resistance at the instant of the discharge step that sample i is the first under: the
// voltage drop over the current at the first two samples under the step, extrapolated to the
// step's start on the square root of the time since it (a diffusion polarisation's short-time
// response), with the cycler's step time; NaN where the step time is not logged or the two
// samples are not in one step. The drop's size at the first sample depends on when the cycler
// logged it (0-30 s after the step in CS2_35); at the step's instant it does not.
double discharge_onset_ohm(const EstimateData& d, std::size_t i, double rest_a, double step_s) {
  if (d.step_time_s.empty() || i + 1 >= d.t_s.size()) return std::nan("");
  const double i1 = d.current_a[i], i2 = d.current_a[i + 1];
  const double tau1 = d.step_time_s[i], tau2 = d.step_time_s[i + 1];
  if (!(i2 > rest_a) || !(tau2 > tau1) || !(tau1 >= 0.0) || d.t_s[i + 1] - d.t_s[i] > kGapFactor * step_s)
    return std::nan("");
  const double r1 = (d.voltage_v[i - 1] - d.voltage_v[i]) / i1, r2 = (d.voltage_v[i - 1] - d.voltage_v[i + 1]) / i2;
  const double s1 = std::sqrt(tau1), s2 = std::sqrt(tau2);
  return r1 - (r2 - r1) * s1 / (s2 - s1);
}

// The charge from the onset of charging that holds sample j0 to the charge's end.
Counted count_charge(const EstimateData& d, std::size_t j0, double rest_a, double step_s, double lower_v) {
  Counted c;
  std::size_t k = j0;
  while (k > 0 && d.current_a[k - 1] < -rest_a) --k;
  c.started_empty = discharged_to_limit(d, k, rest_a, lower_v);
  if (k > 0 && std::abs(d.current_a[k - 1]) <= rest_a && d.t_s[k] - d.t_s[k - 1] <= kGapFactor * step_s &&
      d.current_a[k] < -rest_a)
    c.r_step_ohm = (d.voltage_v[k] - d.voltage_v[k - 1]) / -d.current_a[k];
  double rest_since = std::nan("");
  for (std::size_t i = k + 1; i < d.t_s.size(); ++i) {
    const double i0 = d.current_a[i - 1], i1 = d.current_a[i], dt = d.t_s[i] - d.t_s[i - 1];
    if (dt > kPowerCycleGapS) break;  // a power cycle: what flowed in it is unknown
    if (i1 > rest_a) {                // a discharge
      c.ended = true;
      if (std::abs(i0) <= rest_a && dt <= kGapFactor * step_s) {
        c.r_discharge_step_ohm = (d.voltage_v[i - 1] - d.voltage_v[i]) / i1;
        c.r_discharge_onset_ohm = discharge_onset_ohm(d, i, rest_a, step_s);
      }
      break;
    }
    if (std::abs(i1) <= rest_a) {
      if (std::isnan(rest_since)) rest_since = d.t_s[i];
      if (d.t_s[i] - rest_since > kLongRestS) {
        c.ended = true;
        break;
      }
    } else {
      rest_since = std::nan("");
    }
    const double q = -0.5 * (std::min(i0, 0.0) + std::min(i1, 0.0)) * dt / 3600.0;
    c.ah += q;
    if (dt > kGapFactor * step_s) c.gap_ah += q;
  }
  return c;
}

}  // namespace

double negative_surface_area_m2(const CellParameters& cell) {
  return cell.negative.surface_area_per_volume_m() * cell.negative.thickness_m * cell.electrode_area_m2;
}

std::vector<ChargeReport> find_charges(const std::vector<EstimateRow>& rows, const EstimateData& data,
                                       const CellParameters& cell, bool learned_only) {
  std::vector<ChargeReport> out;
  if (rows.empty() || data.t_s.size() < 2) return out;
  double imax = 0.0;
  for (double i : data.current_a) imax = std::max(imax, std::abs(i));
  const double rest_a = kRestShare * imax, step_s = median_step(data.t_s);
  const double area_m2 = negative_surface_area_m2(cell);
  double film_ref = std::nan("");
  bool learned_before = false;
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (rows[i].mode != fw::Mode::cc_charge || (i > 0 && rows[i - 1].mode == fw::Mode::cc_charge)) continue;
    std::size_t e = i;
    bool learned = rows[i].rcsi_active;
    while (e + 1 < rows.size() && rows[e + 1].mode == fw::Mode::cc_charge) {
      ++e;  // not inside `learned || ...`: once learned, the short circuit skipped it and the loop never ended
      learned = learned || rows[e].rcsi_active;
    }
    if (learned_only && !learned) continue;
    const auto j0 = static_cast<std::size_t>(std::lower_bound(data.t_s.begin(), data.t_s.end(), rows[i].t_s) -
                                             data.t_s.begin());
    const Counted q = count_charge(data, std::min(j0, data.t_s.size() - 1), rest_a, step_s, cell.lower_voltage_v);
    ChargeReport c{};
    c.index = static_cast<int>(out.size()) + 1;
    c.cycle = rows[i].cycle;
    c.t_start_s = rows[i].t_s;
    c.t_end_s = rows[e].t_s;
    c.counted_ah = q.ah;
    c.counted_sd_ah = std::hypot(0.5 * q.gap_ah, kSensorGainSd * q.ah);
    // The model's capacity is an estimate once the inventory was identified in this charge or an
    // earlier one; before that it is the nominal cell's, and the counted charge stands in.
    learned_before = learned_before || learned;
    c.capacity_estimated = learned_before && std::isfinite(rows[e].capacity_est_ah);
    // The count is a capacity only over a whole charge: from a discharge to the lower limit to a
    // rest or a discharge (a charge from part-way, or cut by a power cycle, counts part of it).
    c.counted_complete = q.started_empty && q.ended;
    c.capacity_ah = std::nan("");
    c.capacity_sd_ah = std::nan("");
    if (c.capacity_estimated) {
      c.capacity_ah = rows[e].capacity_est_ah;
      c.capacity_sd_ah = rows[e].capacity_sd_ah;
    } else if (c.counted_complete) {
      c.capacity_ah = c.counted_ah;
      c.capacity_sd_ah = c.counted_sd_ah;
    }
    c.r_film_ohm_m2 = rows[e].r_film_est_ohm_m2;
    c.r_film_sd_ohm_m2 = rows[e].r_film_sd_ohm_m2;
    if (std::isnan(film_ref) && (learned || !learned_only)) film_ref = c.r_film_ohm_m2;
    c.r_growth_ohm = (c.r_film_ohm_m2 - film_ref) / area_m2;
    c.r_step_ohm = q.r_step_ohm;
    c.r_discharge_step_ohm = q.r_discharge_step_ohm;
    c.r_discharge_onset_ohm = q.r_discharge_onset_ohm;
    c.learned = learned;
    out.push_back(c);
  }
  return out;
}

nlohmann::json charges_json(const std::vector<ChargeReport>& charges) {
  const auto num = [](double v) { return std::isfinite(v) ? nlohmann::json(v) : nlohmann::json(nullptr); };
  nlohmann::json a = nlohmann::json::array();
  for (const ChargeReport& c : charges)
    a.push_back({{"index", c.index},
                 {"cycle", c.cycle},
                 {"t_start_s", c.t_start_s},
                 {"t_end_s", c.t_end_s},
                 {"capacity_ah", num(c.capacity_ah)},
                 {"capacity_sd_ah", num(c.capacity_sd_ah)},
                 {"capacity_source", c.capacity_estimated ? "estimator" : "counted"},
                 {"counted_ah", num(c.counted_ah)},
                 {"counted_sd_ah", num(c.counted_sd_ah)},
                 {"counted_complete", c.counted_complete},
                 {"r_film_ohm_m2", num(c.r_film_ohm_m2)},
                 {"r_film_sd_ohm_m2", num(c.r_film_sd_ohm_m2)},
                 {"r_growth_ohm", num(c.r_growth_ohm)},
                 {"r_step_ohm", num(c.r_step_ohm)},
                 {"r_discharge_step_ohm", num(c.r_discharge_step_ohm)},
                 {"r_discharge_onset_ohm", num(c.r_discharge_onset_ohm)}});
  return a;
}

}  // namespace bms
