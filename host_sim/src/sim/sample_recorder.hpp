#pragma once
// What the truth runs record at each output time, shared by the cycler and the profile drive.
#include <vector>

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
    return s;
  }

 private:
  const DfnModel& m_;
  double r0_;
};

inline std::vector<double> initial_state_of(const DfnModel& model, const SimulationConfig& cfg) {
  return model.initial_state(cfg.ic.stoich_neg, cfg.ic.stoich_pos, cfg.ic.electrolyte_mol_m3,
                             cfg.ic.r_film_ohm_m2);
}

}  // namespace bms::sim_detail
