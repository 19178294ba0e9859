#include "diagnosis/report.hpp"

#include <fmt/format.h>

#include <sstream>

#include "diagnosis/plots.hpp"
#include "io/atomic_file.hpp"

namespace bms::diagnosis {

namespace {

std::string fmt_value(Effect e, double v) {
  switch (e) {
    case Effect::contact_resistance: return fmt::format("{:.4g} mohm", 1e3 * v);
    case Effect::hysteresis: return fmt::format("{:.4g} mV", 1e3 * v);
    case Effect::current_offset: return fmt::format("{:.4g} mA", 1e3 * v);
    case Effect::current_gain: return fmt::format("{:.4g} %", 100.0 * v);
    case Effect::thermal: return fmt::format("{:.4g} W/K", v);
    case Effect::particle_size: return fmt::format("sigma {:.4g}", v);
    case Effect::none: break;
  }
  return "-";
}

void write_residual_csv(const std::filesystem::path& file, const DiagnosisResult& r) {
  AtomicFileWriter w(file);
  w.append(
      "case,t_s,mode,current_meas_a,voltage_meas_v,voltage_before_v,voltage_after_v,residual_before_mv,"
      "residual_after_mv,soc,split\n");
  std::string line;
  for (std::size_t c = 0; c < r.cases.size(); ++c) {
    const auto& cr = r.cases[c];
    const auto& rec = *cr.record;
    for (std::size_t k = 0; k < rec.t_s.size(); ++k) {
      line.clear();
      fmt::format_to(std::back_inserter(line), "{},{:.6f},{},{:.6f},{:.6f},{:.6f},{:.6f},{:.4f},{:.4f},{:.5f},{}\n", c,
                     rec.t_s[k], mode_name(rec.mode[k]), rec.current_a[k], rec.voltage_v[k], cr.before.voltage_v[k],
                     cr.after.voltage_v[k], cr.residual_before_mv[k], cr.residual_after_mv[k], cr.soc[k],
                     cr.train[k] ? "train" : "validate");
      w.append(line);
    }
  }
  w.commit();
}

nlohmann::json groups_json(const Characterisation& ch) {
  nlohmann::json a = nlohmann::json::array();
  for (const auto& g : ch.groups)
    a.push_back({{"dimension", g.dimension}, {"label", g.label}, {"samples", g.samples}, {"mean_mv", g.mean_mv},
                 {"rms_mv", g.rms_mv}});
  return a;
}

void characterisation_md(std::ostringstream& md, const Characterisation& before, const Characterisation& after) {
  md << "| by | group | samples | mean before mV | RMS before mV | mean after mV | RMS after mV |\n"
        "|---|---|---|---|---|---|---|\n";
  for (std::size_t k = 0; k < before.groups.size(); ++k) {
    const auto& b = before.groups[k];
    const ResidualGroup* a = nullptr;
    for (const auto& g : after.groups)
      if (g.dimension == b.dimension && g.label == b.label) a = &g;
    md << fmt::format("| {} | {} | {} | {:.3f} | {:.3f} | {} | {} |\n", b.dimension, b.label, b.samples, b.mean_mv,
                      b.rms_mv, a ? fmt::format("{:.3f}", a->mean_mv) : "-", a ? fmt::format("{:.3f}", a->rms_mv) : "-");
  }
  if (before.signature.valid)
    md << fmt::format(
        "\nLinear signature of the residual before (least squares over the samples with current, residual = c + R I + "
        "h sign(I)): c = {:.3f} mV, R = {:.4f} mohm, h = {:.3f} mV. A contact resistance the model lacks shows as R > 0, "
        "hysteresis as h > 0.\n",
        before.signature.offset_mv, before.signature.r_apparent_mohm, before.signature.h_apparent_mv);
}

}  // namespace

nlohmann::json summary_json(const DiagnosisResult& r, const ReportContext& ctx) {
  nlohmann::json j;
  j["effect"] = effect_name(r.selection.effect);
  j["parameters"] = nlohmann::json::object();
  if (r.selection.effect != Effect::none) j["parameters"][parameter_name(r.selection.effect)] = r.selection.value;
  j["rmse_before_mv"] = r.rmse_before_mv;
  j["rmse_after_mv"] = r.rmse_after_mv;
  j["max_abs_before_mv"] = r.max_abs_before_mv;
  j["max_abs_after_mv"] = r.max_abs_after_mv;
  j["candidates"] = nlohmann::json::array();
  for (const auto& c : r.candidates) {
    nlohmann::json cj{{"effect", effect_name(c.effect)}, {"available", c.available}};
    if (c.available) {
      cj["rmse_after_mv"] = c.rmse_after_mv;
      cj["score"] = c.heldout_rmse_mv;
      cj["max_abs_after_mv"] = c.max_abs_after_mv;
      cj["train_rmse_mv"] = c.train_rmse_mv;
      cj["evaluations"] = c.evaluations;
      if (c.effect != Effect::none) cj["parameters"] = {{parameter_name(c.effect), c.value}};
    } else {
      cj["rmse_after_mv"] = nullptr;
      cj["score"] = nullptr;
    }
    if (!c.note.empty()) cj["note"] = c.note;
    j["candidates"].push_back(cj);
  }
  j["reason"] = r.selection.reason;
  j["score"] = "held-out RMSE in mV (lower is better): parameter fitted on the training samples, error on the others";
  j["heldout_before_mv"] = r.heldout_before_mv;
  j["heldout_after_mv"] = r.heldout_after_mv;
  if (!r.excitation_note.empty()) j["excitation_note"] = r.excitation_note;
  j["cases"] = nlohmann::json::array();
  for (const auto& c : r.cases) {
    nlohmann::json cj{{"data", c.record->source},
                      {"role", c.role},
                      {"samples", c.record->t_s.size()},
                      {"excitation", c.excitation.describe()},
                      {"rmse_before_mv", c.rmse_before_mv},
                      {"rmse_after_mv", c.rmse_after_mv},
                      {"max_abs_before_mv", c.max_abs_before_mv},
                      {"max_abs_after_mv", c.max_abs_after_mv},
                      {"residual_before", groups_json(c.char_before)},
                      {"residual_after", groups_json(c.char_after)}};
    if (c.char_before.signature.valid)
      cj["signature_before"] = {{"offset_mv", c.char_before.signature.offset_mv},
                                {"r_apparent_mohm", c.char_before.signature.r_apparent_mohm},
                                {"h_apparent_mv", c.char_before.signature.h_apparent_mv}};
    if (!c.before.note.empty()) cj["note"] = c.before.note;
    j["cases"].push_back(cj);
  }
  const auto& s = ctx.settings;
  j["cell"] = ctx.cell;
  j["mesh"] = {{"search", {s.search_mesh.n_neg, s.search_mesh.n_r}}, {"final", {s.final_mesh.n_neg, s.final_mesh.n_r}}};
  j["rtol"] = s.rtol;
  j["wall_s"] = r.wall_s;
  return j;
}

std::vector<std::string> write_report(const std::filesystem::path& dir, const DiagnosisResult& r,
                                      const ReportContext& ctx) {
  std::filesystem::create_directories(dir);
  write_residual_csv(dir / "residual.csv", r);
  std::size_t samples = 0;
  for (const auto& c : r.cases) samples += c.record->t_s.size();
  const PlotOutcome plots = draw_residual_plots(dir, static_cast<int>(r.cases.size()), samples);

  std::ostringstream md;
  md << "# Residual diagnosis\n\nMade by `" << ctx.command_line << "`.\n\n";
  md << fmt::format("**Diagnosis: `{}`**{}. {}\n\n", effect_name(r.selection.effect),
                    r.selection.effect == Effect::none ? ""
                                                       : fmt::format(", {} = {}", parameter_name(r.selection.effect),
                                                                     fmt_value(r.selection.effect, r.selection.value)),
                    r.selection.reason);
  if (!r.excitation_note.empty()) md << "Note on the data: " << r.excitation_note << ".\n\n";
  md << "## Before and after (final mesh)\n\n| data | role | samples | RMSE before mV | RMSE after mV | max abs before mV | "
        "max abs after mV |\n|---|---|---|---|---|---|---|\n";
  for (const auto& c : r.cases)
    md << fmt::format("| {} | {} | {} | {:.3f} | {:.3f} | {:.3f} | {:.3f} |\n", c.record->source, c.role,
                      c.record->t_s.size(), c.rmse_before_mv, c.rmse_after_mv, c.max_abs_before_mv, c.max_abs_after_mv);
  md << fmt::format("| all | | | {:.3f} | {:.3f} | {:.3f} | {:.3f} |\n", r.rmse_before_mv, r.rmse_after_mv,
                    r.max_abs_before_mv, r.max_abs_after_mv);
  md << fmt::format("\nHeld-out RMSE: {:.3f} mV before, {:.3f} mV after.\n\n", r.heldout_before_mv, r.heldout_after_mv);

  md << "## Candidates\n\nScore = held-out RMSE: each parameter is fitted (grid + golden-section search on the "
        "training samples' RMSE, search mesh) and scored on the samples it was not fitted on (final mesh). "
        "`none` is the plain model.\n\n| effect | fitted parameter | runs | training RMSE mV | score (held-out RMSE) mV | "
        "RMSE all mV | max abs mV | note |\n|---|---|---|---|---|---|---|---|\n";
  for (const auto& c : r.candidates) {
    if (!c.available) {
      md << fmt::format("| {} | - | - | - | - | - | - | {} |\n", effect_name(c.effect), c.note);
      continue;
    }
    md << fmt::format("| {} | {} | {} | {:.3f} | {:.3f} | {:.3f} | {:.3f} | {} |\n", effect_name(c.effect),
                      fmt_value(c.effect, c.value), c.evaluations, c.train_rmse_mv, c.heldout_rmse_mv, c.rmse_after_mv,
                      c.max_abs_after_mv, c.note);
  }
  md << "\n## Where the residual is\n\n";
  for (const auto& c : r.cases) {
    md << "### " << c.record->source << "\n\n" << c.excitation.describe() << ".\n\n";
    characterisation_md(md, c.char_before, c.char_after);
    md << "\n";
  }
  md << "## Plots\n\n";
  if (plots.pngs.empty()) {
    md << "No plots: " << plots.problem << ". The numbers above do not depend on them; residual.csv has the data.\n\n";
  } else {
    for (const auto& p : plots.pngs) md << "![" << p << "](" << p << ")\n\n";
  }
  md << "## How it was made\n\n"
        "- The model is the truth DFN driven by the measured current (CV segments too: the cycler's profile control "
        "is current-only) from the cell's default initial state; residual = model - measured voltage.\n"
        "- A current-sensor offset or gain is added by driving the model with the corrected current "
        "(I_true = (I_meas - offset) / (1 + gain)); the other effects are switches of the truth model.\n"
        "- Search runs use a coarse mesh; the plain model's difference between the final and the search mesh is "
        "added to every search run, so the fit sees the effect rather than the mesh.\n"
        "- One record: alternate eighths of it train and validate. Several records: the first trains, the others "
        "validate.\n"
        "- The best candidate is chosen if it cuts the held-out RMSE by 20 % and 0.05 mV, and no other effect comes "
        "within 10 % of its gain; otherwise `none`.\n";
  AtomicFileWriter report(dir / "report.md");
  report.append(md.str());
  report.commit();

  auto j = summary_json(r, ctx);
  j["plots"] = plots.pngs;
  if (!plots.problem.empty()) j["plots_problem"] = plots.problem;
  AtomicFileWriter summary(dir / "summary.json");
  summary.append(j.dump(2) + "\n");
  summary.commit();
  return plots.pngs;
}

}  // namespace bms::diagnosis
