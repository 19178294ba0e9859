#include "simulate_options.hpp"

namespace bms::app {

void register_simulate_options(CLI::App& sub, SimulateOptions& o) {
  sub.add_option("--cell", o.cell, "paper | aboutenergy | lco | nmc | FILE.bpx.json")->capture_default_str();
  sub.add_option("--protocol", o.protocol,
                 "cccv (repeated CC-CV discharge/charge: CC discharge at --current-a to --v-min, CV there to "
                 "--cv-end-current-a, CC charge to --v-max, CV there), an experiment as PyBaMM writes one "
                 "(\"Discharge at 1C until 2.0 V; Rest for 30 minutes; Charge at 2.5 A until 3.6 V; Hold at 3.6 V "
                 "until 50 mA\": steps split by ';', Discharge|Charge at A, mA, xC or C/n, 'for D "
                 "seconds|minutes|hours' and/or 'until V'; Rest for D; Hold at V until A or C/n; repeated --cycles "
                 "times), or csv:FILE (drive with a measured current: truth.csv, About:Energy "
                 "'Time [s],I[A],U[V]' format, or a cycler's export: Arbin, Maccor, Neware, BioLogic .mpt, NASA PCoE)")
      ->capture_default_str();
  sub.add_option("--current-sign", o.current_sign,
                 "discharge-positive | charge-positive: the sign of a csv:FILE's current (default: by its layout, "
                 "checked against the voltage's response; a contradiction exits 2)");
  sub.add_option("--cycles", o.cycles, "Number of CCCV cycles")
      ->capture_default_str()
      ->check(CLI::Validator(
          [](std::string& v) -> std::string {
            const bool digits = !v.empty() && v.size() <= 6 && v.find_first_not_of("0123456789") == std::string::npos;
            if (digits && std::stoi(v) >= 1 && std::stoi(v) <= 100000) return {};
            return "'" + v + "' is not a whole number of cycles from 1 to 100000 (written out: 1000, not 1e3)";
          },
          "INT in [1 - 100000]"));
  sub.add_option("--current-a", o.current_a, "CC current magnitude (A)")->capture_default_str();
  sub.add_option("--dt", o.dt_s, "Output sample time (s)")->capture_default_str();
  sub.add_option("--noise-v-mv", o.noise_v_mv, "Voltage measurement noise, standard deviation (mV)")->capture_default_str();
  sub.add_option("--noise-i-ma", o.noise_i_ma, "Current measurement noise, standard deviation (mA)")->capture_default_str();
  sub.add_option("--noise-t-k", o.noise_t_k,
                 "Temperature sensor noise, standard deviation (K), in the temperature_meas_k column")
      ->capture_default_str();
  sub.add_option("--seed", o.seed, "Noise seed")->capture_default_str();
  sub.add_option("--ic-error-pct", o.ic_error_pct,
                 "Initial-condition error P: scales c_e, theta_n, theta_p by (1 + P/100)")->capture_default_str();
  sub.add_option("--effect", o.effects,
                 "Undeclared effect NAME=VALUE (repeatable): contact_resistance (ohm), hysteresis (V, half the "
                 "gap between the charge and discharge OCV branches; starts on the charge branch), current_offset "
                 "(A), current_gain (relative), temperature_offset (K: the temperature sensor reads this much high), voltage_offset (V: the voltage sensor reads this much high), thermal (lumped thermal model with Arrhenius properties; VALUE = "
                 "heat-transfer coefficient to ambient in W/K, e.g. 0.05 for an 18650 in still air), particle_size (cathode "
                 "particle-size distribution: VALUE = log-space standard deviation sigma of a lognormal of radii, "
                 "3 populations, same surface area), particle_size_negative (the same for the anode; not with the side "
                 "reaction), diffusivity_profile_positive (cathode solid diffusivity falling towards full lithiation: "
                 "VALUE = log10 of the factor on D at stoichiometry 1, log-linear from the knee, e.g. -2), "
                 "diffusivity_profile_positive_knee (the knee stoichiometry, default 0.5), resistive_reactant_positive "
                 "(cathode resistive reactant: an ohmic drop j R in each cathode particle's overpotential; VALUE = R in "
                 "ohm m2 of particle surface below the knee, e.g. 0.2), resistive_reactant_positive_log10 (decades R "
                 "rises from the knee to full lithiation, at the particle's mean stoichiometry), "
                 "resistive_reactant_positive_knee (default 0.5), resistive_reactant_positive_ea (J/mol: the reactant's "
                 "resistance follows the cell temperature, Arrhenius from the cell's reference temperature; with "
                 "thermal or --set temperature_k; default 0), none");
  sub.add_option("--set", o.set,
                 "Hidden truth parameter NAME=VALUE (repeatable; the truth only, never the estimator), e.g. "
                 "film_growth_scale=2, inventory_scale=0.97, temperature_k=288.15; `bmssim simulate --list-params` "
                 "lists every name with its nominal value, unit and range");
  sub.add_option("--v-min", o.v_min,
                 "Lower voltage limit (V; default: the cell's): cccv discharges to it; an experiment's voltages must "
                 "lie within 0.5 V of the window; a csv: drive stops only 0.5 V below it (a measured record may "
                 "overshoot the limits a little)");
  sub.add_option("--v-max", o.v_max, "Upper voltage limit (V; default: the cell's); as --v-min, 0.5 V above it for csv:");
  sub.add_option("--cv-end-current-a", o.cv_end_current_a, "CV phases end below this current (A)")->capture_default_str();
  sub.add_option("--points", o.points, "Finite volumes per region (anode, separator, cathode)")->capture_default_str()->check(CLI::Range(2, 400));
  sub.add_option("--radial", o.radial, "Finite volumes per particle")->capture_default_str()->check(CLI::Range(3, 400));
  sub.add_option("--rtol", o.rtol, "IDA relative tolerance")->capture_default_str();
  sub.add_flag("--quiet", o.quiet, "No progress output");
}

}  // namespace bms::app
