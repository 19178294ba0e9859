// See replay_tick.hpp.
#include "replay_tick.hpp"

#include <bms/fw/config/make_config.hpp>

namespace bms::target {

namespace {
Model initial_model() {
  Model m;
  m.init_default();
  return m;
}
}  // namespace

// The default profile of every caller (bms/fw/config/make_config.hpp): best, in double (host,
// Cortex-M7) and in float (Cortex-M4F; the numerics that keep the film signal in float are
// described in reduced_cell.hpp and docs/results/target.md).
Core::Config firmware_config() {
  return bms::fw::make_config<Core>(bms::fw::nominal_cell_of<Scalar, Cell>(), kProfile);
}

Core::Config record_config(double dt_s, double sample_step_s, bool learning) {
  bms::fw::Overrides o;
  if (!learning) o.learning = false;  // what estimate's --no-learning gives
  Core::Config cfg = firmware_config();
  (void)bms::fw::make_config<Core>(bms::fw::nominal_cell_of<Scalar, Cell>(), kProfile, o, cfg);  // learning: used by every profile
  cfg.dt_s = static_cast<Scalar>(dt_s);
  bms::fw::adapt_to_sample_step(cfg, sample_step_s);
  return cfg;
}

Model initial_firmware_model() { return initial_model(); }

ReplayFirmware::ReplayFirmware() : model(initial_model()), core(firmware_config(), model) {}

ReplayFirmware::ReplayFirmware(const Core::Config& config) : model(initial_model()), core(config, model) {}

TickOutput replay_tick(ReplayFirmware& fw, Scalar voltage_v, Scalar current_a) {
  return fw.core.tick({voltage_v, current_a, true});
}

TickOutput replay_tick(ReplayFirmware& fw, Scalar voltage_v, Scalar current_a, Scalar temperature_k) {
  return fw.core.tick({voltage_v, current_a, true, temperature_k});
}

bms::fw::ModelTickResult<Scalar> newton_cap_probe(const ReplayFirmware& fw) {
  Model probe = fw.model;
  // 5 V: the top of the tick's plausible range, far above what the cell can show.
  return probe.step_voltage(Scalar(5), fw.core.r_film_ohm_m2(), fw.core.config().dt_s);
}

bool resync_probe(const ReplayFirmware& fw) {
  Model probe = fw.model;
  const Scalar film = fw.core.r_film_ohm_m2();
  const Scalar dt = fw.core.config().dt_s;
  const Scalar voltage_v = probe.peek_voltage(Scalar(0.2), film, dt) + Scalar(0.005);
  return probe.resync(voltage_v, Scalar(0.2), film, dt, probe.solid_inventory_mol() * Scalar(1.005));
}

TickOutput catch_up_probe(ReplayFirmware& fw, unsigned gap, Scalar voltage_v, Scalar current_a) {
  for (unsigned k = 0; k < gap; ++k) fw.core.tick({Scalar(0), Scalar(0), false});
  return fw.core.tick({voltage_v, current_a, true});
}

}  // namespace bms::target
