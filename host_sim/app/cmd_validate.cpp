// bmssim validate: the truth model's checks, with the numbers for docs/results/truth-model.md.
#include <cstdio>
#include <filesystem>
#include <memory>
#include <sstream>
#include <string>

#include <fmt/format.h>

#include "cell/paper_cell.hpp"
#include "commands.hpp"
#include "io/output_folder.hpp"
#include "sim/truth_output.hpp"
#include "studies/truth_validation.hpp"

namespace bms::app {

namespace {

void add_conservation(nlohmann::json& j, std::ostringstream& md) {
  std::fprintf(stderr, "validate: conservation (1 paper cycle, side reaction off and on)\n");
  const auto c = check_conservation(make_paper_cell(), 1);
  j["conservation"] = {{"inventory_drift_rel_per_cycle", c.inventory_drift_rel_per_cycle},
                       {"max_solid_lithium_drift_rel", c.max_solid_lithium_drift_rel},
                       {"max_stoich_sum_error", c.max_stoich_sum_error},
                       {"throughput_vs_cathode_rel", c.throughput_vs_cathode_rel},
                       {"li_loss_mol", c.li_loss_mol},
                       {"li_side_current_mol", c.li_side_current_mol},
                       {"li_loss_rel_error", c.li_loss_rel_error},
                       {"charge_state_vs_trapezoid_rel", c.charge_state_vs_trapezoid_rel}};
  md << "## Conservation (paper cell, one CCCV cycle)\n\n| check | value |\n|---|---|\n"
     << fmt::format("| side reaction off: lithium inventory drift per cycle (relative) | {:.2e} |\n", c.inventory_drift_rel_per_cycle)
     << fmt::format("| side reaction off: max drift of C_n θn + C_p θp (relative) | {:.2e} |\n", c.max_solid_lithium_drift_rel)
     << fmt::format("| side reaction off: max abs(θn + θp - 1) | {:.2e} |\n", c.max_stoich_sum_error)
     << fmt::format("| side reaction off: abs(∫I dt - F ΔN_cathode) / capacity | {:.2e} |\n", c.throughput_vs_cathode_rel)
     << fmt::format("| side reaction on: lithium lost (mol) | {:.6e} |\n", c.li_loss_mol)
     << fmt::format("| side reaction on: ∫ A L_n J_s dt / F (mol, trapezoid of 0.2 s samples) | {:.6e} |\n", c.li_side_current_mol)
     << fmt::format("| relative difference | {:.2e} |\n", c.li_loss_rel_error)
     << fmt::format("| integrator's ∫I dt vs trapezoid of the samples (relative to capacity) | {:.2e} |\n\n", c.charge_state_vs_trapezoid_rel);
}

void add_convergence(nlohmann::json& j, std::ostringstream& md, int finest) {
  std::vector<int> meshes;
  for (int p = 10; p <= finest; p *= 2) meshes.push_back(p);
  std::fprintf(stderr, "validate: mesh convergence (one paper cycle per mesh and its double)\n");
  const auto rows = check_mesh_convergence(make_paper_cell(), meshes);
  md << "## Mesh convergence (paper cell, one CCCV cycle, voltage vs the doubled mesh in CC phases)\n\n"
        "| points per region = radial | unknowns | max mV | RMS mV | max mV, interior | RMS mV, interior | "
        "max phase-duration shift s | wall s |\n|---|---|---|---|---|---|---|---|\n";
  j["convergence"] = nlohmann::json::array();
  for (const auto& r : rows) {
    j["convergence"].push_back({{"points", r.points}, {"radial", r.radial}, {"unknowns", r.unknowns},
                                {"max_diff_mv", r.max_diff_mv}, {"rms_diff_mv", r.rms_diff_mv},
                                {"interior_max_diff_mv", r.interior_max_diff_mv},
                                {"interior_rms_diff_mv", r.interior_rms_diff_mv},
                                {"max_phase_end_shift_s", r.max_phase_end_shift_s}, {"wall_s", r.wall_s}});
    md << fmt::format("| {} | {} | {:.3f} | {:.4f} | {:.3f} | {:.4f} | {:.2f} | {:.2f} |\n", r.points, r.unknowns,
                      r.max_diff_mv, r.rms_diff_mv, r.interior_max_diff_mv, r.interior_rms_diff_mv,
                      r.max_phase_end_shift_s, r.wall_s);
  }
  md << "\n'interior' leaves out the first and last 30 s of each CC phase.\n\n";
}

void add_paper_observables(nlohmann::json& j, std::ostringstream& md) {
  std::fprintf(stderr, "validate: paper observables (5 cycles, and one at 2.495 A)\n");
  const auto o = paper_observables(5);
  j["paper"] = {{"growth_pct_per_cycle", o.growth_pct_per_cycle},
                {"growth_share_cc_charge", o.growth_share_cc_charge},
                {"growth_share_cv_charge", o.growth_share_cv_charge},
                {"growth_share_discharge", o.growth_share_discharge},
                {"dv_successive_cc_charge_mv", o.dv_successive_cc_charge_mv},
                {"film_drop_growth_mv", o.film_drop_growth_mv},
                {"dv_current_2p495_mv", o.dv_current_2p495_mv},
                {"dv_current_2p495_start_mv", o.dv_current_2p495_start_mv},
                {"theta", {o.theta_m1, o.theta_n1}}};
  md << "## The paper's observables (paper cell, 5 CCCV cycles at 2.5 A)\n\n| observable | paper | ours |\n|---|---|---|\n";
  std::string g, dv;
  for (double x : o.growth_pct_per_cycle) g += fmt::format("{:.3f} ", x);
  for (double x : o.dv_successive_cc_charge_mv) dv += fmt::format("{:.3f} ", x);
  md << "| film-resistance growth per cycle, % | about 1.5 | " << g << "|\n"
     << fmt::format("| share of the growth in CC charge / CV charge / discharge | mainly CC charge | {:.3f} / {:.3f} / {:.3f} |\n",
                    o.growth_share_cc_charge, o.growth_share_cv_charge, o.growth_share_discharge)
     << "| voltage change in CC charge between successive cycles (median), mV | 0.1-0.2 | " << dv << "|\n"
     << fmt::format("| expected from film growth: dR x CC pore-wall current, mV | - | {:.3f} |\n", o.film_drop_growth_mv)
     << fmt::format("| voltage difference 2.50 A vs 2.495 A in CC charge (median over the phase), mV | about 0.1 | {:.3f} |\n",
                    o.dv_current_2p495_mv)
     << fmt::format("| true subsystem theta [M1, N1] at T = 0.2 s | [1, -2.3712e-10] | [{}, {:.5e}] |\n\n", o.theta_m1,
                    o.theta_n1);
}

void add_aboutenergy(nlohmann::json& j, std::ostringstream& md) {
  std::fprintf(stderr, "validate: About:Energy discharges (default mesh, and PyBaMM's 16/16)\n");
  md << "## Against measurement: About:Energy LFP 18650, BPX parameters, isothermal DFN\n\n"
        "| case | mesh | PyBaMM RMSE mV | ours RMSE mV | ours / PyBaMM | max abs mV | wall s |\n|---|---|---|---|---|---|---|\n";
  j["aboutenergy"] = nlohmann::json::array();
  for (const DfnMesh& mesh : {DfnMesh{}, DfnMesh{16, 16, 16, 16}}) {
    for (const auto& mc : compare_aboutenergy(mesh)) {
      const std::string mname = fmt::format("{}/{}", mesh.n_neg, mesh.n_r);
      j["aboutenergy"].push_back({{"case", mc.name}, {"mesh", mname}, {"pybamm_rmse_mv", mc.pybamm_rmse_mv},
                                  {"rmse_mv", mc.rmse_mv}, {"max_abs_mv", mc.max_abs_mv}, {"wall_s", mc.wall_s},
                                  {"samples", mc.samples}, {"note", mc.note}});
      md << fmt::format("| {} | {} | {:.3f} | {:.3f} | {:.3f} | {:.1f} | {:.3f} |\n", mc.name, mname, mc.pybamm_rmse_mv,
                        mc.rmse_mv, mc.rmse_mv / mc.pybamm_rmse_mv, mc.max_abs_mv, mc.wall_s);
    }
  }
}

}  // namespace

Runner add_validate(CLI::App& app) {
  auto* sub = app.add_subcommand("validate",
                                 "Check the truth model: conservation, mesh convergence, the paper's observables, "
                                 "and the About:Energy discharges against PyBaMM's published RMSE");
  auto out_dir = std::make_shared<std::string>();
  auto fine = std::make_shared<int>(40);
  sub->add_option("--out", *out_dir, "Output folder (summary.json, report.md)")->required();
  sub->add_option("--finest", *fine, "Finest base mesh of the convergence study (compared with its double)")
      ->capture_default_str()->check(CLI::Range(10, 80));
  return [out_dir, fine]() {
    OutputFolder folder(*out_dir);
    nlohmann::json j;
    std::ostringstream md;
    md << "# Truth-model validation\n\nMade by `bmssim validate --out " << *out_dir << "`.\n\n";
    add_conservation(j, md);
    add_convergence(j, md, *fine);
    add_paper_observables(j, md);
    add_aboutenergy(j, md);
    write_file_atomically(folder.staging() / "report.md", md.str());
    write_file_atomically(folder.staging() / "summary.json", j.dump(2) + "\n");
    folder.commit();
    std::fputs(md.str().c_str(), stdout);
    return 0;
  };
}

}  // namespace bms::app
