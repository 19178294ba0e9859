#pragma once
// What the truth runs record at each output time, shared by the cycler and the profile drive.
#include <cmath>
#include <vector>

#include "bms/fw/model/open_circuit_capacity.hpp"
#include "dfn/dfn_model.hpp"
#include "sim/cycler.hpp"

namespace bms::sim_detail {

class Recorder {
 public:
  Recorder(const DfnModel& m, double r0) : m_(m), r0_(r0) {}

  SampleRecord sample(double t, int cycle, Mode mode, const std::vector<double>& y) const {
    SampleRecord s{};
    s.t_s = t;
    s.cycle = cycle;
    s.mode = mode;
    s.current_a = y[m_.idx_current()];
    s.voltage_v = m_.terminal_voltage_v(y.data());
    s.r_film_ohm_m2 = y[m_.idx_film()];
    s.j_s_a_m3 = m_.mean_side_current_a_m2(y.data()) * m_.cell().negative.surface_area_per_volume_m();
    s.li_loss_ah = m_.lithium_loss_mol(s.r_film_ohm_m2, r0_) * kFaradayC_mol / 3600.0;
    s.temperature_k = m_.temperature_k(y.data());
    s.charge_ah = y[m_.idx_charge()];
    s.inventory_mol = m_.lithium_inventory_mol(y.data());
    s.stoich_neg = m_.mean_stoich(y.data(), true);
    s.stoich_pos = m_.mean_stoich(y.data(), false);
    s.hysteresis_v = m_.hysteresis_voltage_v(y.data());
    if (m_.effects().thermal_on()) s.heat_w = m_.heat_rates(y.data()).total_w();
    s.capacity_ah = capacity_ah(s.stoich_neg, s.stoich_pos);
    return s;
  }

 private:
  // The open-circuit capacity of the solid lithium (the contract's capacity_ah), recomputed only
  // when the inventory has moved (it changes by about 1e-7 per tick through the side reaction).
  double capacity_ah(double stoich_neg, double stoich_pos) const {
    const CellParameters& c = m_.cell();
    const double cap_n = c.negative.max_concentration_mol_m3 * c.negative.solid_fraction * c.negative.thickness_m *
                         c.electrode_area_m2;
    const double cap_p = c.positive.max_concentration_mol_m3 * c.positive.solid_fraction * c.positive.thickness_m *
                         c.electrode_area_m2;
    const double inventory_mol = stoich_neg * cap_n + stoich_pos * cap_p;
    if (std::abs(inventory_mol - cached_inventory_mol_) <= 1e-9 * inventory_mol) return cached_capacity_ah_;
    const auto un = [&c](double x) { return c.negative.ocp_v->value(x); };
    const auto up = [&c](double x) { return c.positive.ocp_v->value(x); };
    cached_inventory_mol_ = inventory_mol;
    cached_capacity_ah_ =
        fw::open_circuit_capacity_ah(inventory_mol, cap_n, cap_p, c.lower_voltage_v, c.upper_voltage_v, un, up);
    return cached_capacity_ah_;
  }

  const DfnModel& m_;
  double r0_;
  mutable double cached_inventory_mol_ = -1.0;
  mutable double cached_capacity_ah_ = 0.0;
};

inline std::vector<double> initial_state_of(const DfnModel& model, const SimulationConfig& cfg) {
  return model.initial_state(cfg.ic.stoich_neg, cfg.ic.stoich_pos, cfg.ic.electrolyte_mol_m3,
                             cfg.ic.r_film_ohm_m2);
}

}  // namespace bms::sim_detail
