// See replay_tick.hpp.
#include "replay_tick.hpp"

namespace bms::target {

namespace {
Model initial_model() {
  Model m;
  m.init_default();
  return m;
}
}  // namespace

ReplayFirmware::ReplayFirmware() : model(initial_model()), core(Core::Config{}, model) {}

TickOutput replay_tick(ReplayFirmware& fw, Scalar voltage_v, Scalar current_a) {
  return fw.core.tick({voltage_v, current_a, true});
}

bms::fw::ModelTickResult<Scalar> newton_cap_probe(const ReplayFirmware& fw) {
  Model probe = fw.model;
  // 5 V: the top of the tick's plausible range, far above what the cell can show.
  return probe.step_voltage(Scalar(5), fw.core.r_film_ohm_m2(), fw.core.config().dt_s);
}

}  // namespace bms::target
