#include "estimation/film_bound.hpp"

#include <cmath>
#include <map>

#include <Eigen/Dense>

#include "bms/fw/model/reduced_cell.hpp"
#include "cell/reduced_cell_record.hpp"

namespace bms {

namespace {

using Mat3 = Eigen::Matrix3d;
using Vec3 = Eigen::Vector3d;

// sqrt(a^T J^-1 a), or NaN when J is not positive definite.
double bound_of(const Mat3& j, const Vec3& a) {
  const Eigen::LDLT<Mat3> f(j);
  if (f.info() != Eigen::Success || !f.isPositive() || (f.vectorD().array() <= 0.0).any()) return std::nan("");
  return std::sqrt(a.dot(f.solve(a)));
}

// dV/dI [ohm] of a reduced model at rest at these stoichiometries, one tick into a charge at current_a.
template <class Model>
double charge_start_resistance_ohm(double stoich_neg, double stoich_pos, double electrolyte_mol_m3, double r_film_ohm_m2,
                                   double current_a) {
  Model cell;
  cell.init(stoich_neg, stoich_pos, electrolyte_mol_m3);
  const double dt = 0.2, di = 1e-3;
  return (cell.peek_voltage(-current_a + di, r_film_ohm_m2, dt) - cell.peek_voltage(-current_a, r_film_ohm_m2, dt)) / -di;
}

}  // namespace

FilmBound film_cramer_rao(const std::vector<EstimateRow>& rows, double sigma_v) {
  FilmBound out;
  if (!(sigma_v > 0.0)) return out;
  Mat3 j = Mat3::Zero();
  std::size_t learned = 0;
  std::map<int, std::size_t> last_cc;  // cycle -> last CC-charge row
  for (std::size_t i = 0; i < rows.size(); ++i)
    if (rows[i].mode == fw::Mode::cc_charge) last_cc[rows[i].cycle] = i;
  auto cycle_it = last_cc.begin();
  const double w = 1.0 / (sigma_v * sigma_v);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    const auto& r = rows[i];
    if (r.rcsi_active) {
      const Vec3 phi(r.markov_v_per_ohm_m2, r.markov_v_per_ohm_m2 * r.growth_ohm_m2, r.inventory_sensitivity_v);
      j += w * phi * phi.transpose();
      ++learned;
    }
    while (cycle_it != last_cc.end() && cycle_it->second == i) {
      const Vec3 a(1.0, r.growth_ohm_m2, 0.0);
      const double sd = bound_of(j, a);
      const double nu_sd = bound_of(j, Vec3(0.0, 0.0, 1.0));
      out.cycles.push_back({cycle_it->first, sd / r.r_film_true_ohm_m2 * 100.0, nu_sd * 100.0});
      ++cycle_it;
    }
  }
  if (learned == 0) return out;
  out.r0_sd_ohm_m2 = bound_of(j, Vec3(1.0, 0.0, 0.0));
  out.gain_sd = bound_of(j, Vec3(0.0, 1.0, 0.0));
  out.inventory_sd_pct = bound_of(j, Vec3(0.0, 0.0, 1.0)) * 100.0;
  out.valid = std::isfinite(out.r0_sd_ohm_m2) && std::isfinite(out.gain_sd);
  const GrowthSpan span = growth_span(rows);
  if (span.valid) {
    const auto& ref = rows[span.ref];
    const auto& last = rows[span.last];
    out.growth_sd_ohm_m2 = bound_of(j, Vec3(0.0, last.growth_ohm_m2 - ref.growth_ohm_m2, 0.0));
    const double true_growth = last.r_film_true_ohm_m2 - ref.r_film_true_ohm_m2;
    if (true_growth != 0.0) out.growth_sd_pct = out.growth_sd_ohm_m2 / std::abs(true_growth) * 100.0;
  }
  return out;
}

double effective_voltage_noise_v(double sigma_v, double sigma_i, double current_a, const CellParameters& cell) {
  double r_ohm = 0.0;
  if (cell.name == "paper") {
    r_ohm = charge_start_resistance_ohm<fw::ReducedCell<double>>(0.05, 0.95, fw::PaperCellTraits::kElectrolyteInitMolM3,
                                                                 fw::PaperCellTraits::kInitialFilmOhmM2, current_a);
  } else {
    const ReducedCellRecord record = make_reduced_cell_record(cell);
    const RuntimeCellScope scope(record);
    r_ohm = charge_start_resistance_ohm<fw::ReducedCell<double, RuntimeCellTraits, AnyCellMesh>>(
        cell.negative.stoich_min, cell.positive.stoich_min, cell.initial_electrolyte_mol_m3,
        cell.side.enabled ? cell.side.initial_film_resistance_ohm_m2 : 0.0, current_a);
  }
  return std::sqrt(sigma_v * sigma_v + r_ohm * r_ohm * sigma_i * sigma_i);
}

}  // namespace bms
