#include "diagnosis/report.hpp"

#include <fmt/format.h>

#include <cmath>
#include <sstream>

#include "diagnosis/plots.hpp"
#include "io/atomic_file.hpp"

namespace bms::diagnosis {

namespace {

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
  md << "| by | group | samples | mean before mV | RMS before mV | mean fitted mV | RMS fitted mV |\n"
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

namespace {

nlohmann::json knobs_json(const Hypothesis& h) {
  nlohmann::json j = nlohmann::json::object();
  for (const auto& k : h) j[parameter_name(k.effect)] = k.value;
  return j;
}

nlohmann::json names_json(const std::vector<Effect>& e) {
  nlohmann::json j = nlohmann::json::array();
  for (Effect x : e) j.push_back(effect_name(x));
  return j;
}

nlohmann::json adequacy_json(const Adequacy& a) {
  nlohmann::json groups = nlohmann::json::array();
  for (const auto& g : a.above_floor)
    groups.push_back({{"dimension", g.dimension}, {"label", g.label}, {"rms_mv", g.rms_mv}, {"mean_mv", g.mean_mv}});
  return {{"noise_mv", a.noise_mv},         {"numerical_mv", a.numerical_mv},
          {"floor_mv", a.floor_mv},         {"rmse_mv", a.rmse_mv},
          {"at_floor", a.at_floor},         {"lag1_autocorrelation", a.lag1_autocorrelation},
          {"above_floor", groups},          {"verdict", a.verdict}};
}

nlohmann::json candidates_json(const DiagnosisResult& r) {
  nlohmann::json a = nlohmann::json::array();
  for (const auto& c : r.candidates) {
    nlohmann::json cj{{"effect", effect_name(c.effect)}, {"available", c.available}};
    if (c.available) {
      cj["rmse_after_mv"] = c.rmse_after_mv;
      cj["score"] = c.heldout_rmse_mv;
      cj["max_abs_after_mv"] = c.max_abs_after_mv;
      cj["train_rmse_mv"] = c.train_rmse_mv;
      cj["evaluations"] = c.evaluations;
      if (c.effect != Effect::none) cj["parameters"] = knobs_json(c.fitted);
    } else {
      cj["rmse_after_mv"] = nullptr;
      cj["score"] = nullptr;
    }
    if (!c.note.empty()) cj["note"] = c.note;
    a.push_back(cj);
  }
  return a;
}

nlohmann::json cases_json(const DiagnosisResult& r) {
  nlohmann::json a = nlohmann::json::array();
  for (const auto& c : r.cases) {
    nlohmann::json cj{{"data", c.record->source},
                      {"role", c.role},
                      {"samples", c.record->t_s.size()},
                      {"excitation", c.excitation.describe()},
                      {"rmse_before_mv", c.rmse_before_mv},
                      {"rmse_after_mv", r.explained ? c.rmse_after_mv : c.rmse_before_mv},
                      {"max_abs_before_mv", c.max_abs_before_mv},
                      {"max_abs_after_mv", r.explained ? c.max_abs_after_mv : c.max_abs_before_mv},
                      {"heldout_before_mv", c.heldout_before_mv},
                      {"heldout_after_mv", r.explained ? c.heldout_after_mv : c.heldout_before_mv},
                      {"fitted_model", {{"rmse_mv", c.rmse_after_mv}, {"max_abs_mv", c.max_abs_after_mv},
                                        {"heldout_mv", c.heldout_after_mv}}},
                      {"adequacy_before", adequacy_json(c.adequacy_before)},
                      {"adequacy_fitted", adequacy_json(c.adequacy_after)},
                      {"residual_before", groups_json(c.char_before)},
                      {"residual_fitted", groups_json(c.char_after)}};
    if (!c.record->initial_state_note.empty()) cj["initial_state"] = c.record->initial_state_note;
    if (!c.record->layout_note.empty()) cj["layout"] = c.record->layout_note;
    if (c.char_before.signature.valid)
      cj["signature_before"] = {{"offset_mv", c.char_before.signature.offset_mv},
                                {"r_apparent_mohm", c.char_before.signature.r_apparent_mohm},
                                {"h_apparent_mv", c.char_before.signature.h_apparent_mv}};
    if (!c.before.note.empty()) cj["note"] = c.before.note;
    a.push_back(cj);
  }
  return a;
}

nlohmann::json steps_json(const DiagnosisResult& r) {
  nlohmann::json a = nlohmann::json::array();
  for (const auto& s : r.steps) {
    nlohmann::json scores = nlohmann::json::object();
    for (const auto& [e, v] : s.scores) scores[effect_name(e)] = v;
    a.push_back({{"base", names_json(s.base)}, {"chosen", effect_name(s.chosen)}, {"heldout_mv", scores},
                 {"reason", s.reason}});
  }
  return a;
}

nlohmann::json identifiability_json(const DiagnosisResult& r) {
  nlohmann::json a = nlohmann::json::array();
  for (const auto& k : r.identifiability) {
    nlohmann::json j{{"knob", parameter_name(k.knob)}, {"value", k.value}, {"sensitivity_mv", k.sensitivity_mv},
                     {"selected", k.selected}};
    if (k.selected) {
      j["std_error"] = k.std_error;
      j["relative_std_pct"] = std::isfinite(k.relative_std_pct) ? nlohmann::json(k.relative_std_pct) : nlohmann::json();
      j["max_abs_correlation"] = k.max_abs_correlation;
    }
    a.push_back(j);
  }
  return a;
}

}  // namespace

nlohmann::json summary_json(const DiagnosisResult& r, const ReportContext& ctx) {
  nlohmann::json j;
  j["effect"] = effect_name(r.answer);
  j["effects"] = names_json(r.effects);
  j["explained"] = r.explained;
  j["unexplained"] = r.answer == Effect::unexplained;
  j["parameters"] = knobs_json(r.model);
  nlohmann::json notes = nlohmann::json::object();
  for (const auto& k : r.model) notes[parameter_name(k.effect)] = plausibility_note(k.effect, k.value);
  j["plausibility"] = notes;
  j["rmse_before_mv"] = r.rmse_before_mv;
  j["rmse_after_mv"] = r.explained ? r.rmse_after_mv : r.rmse_before_mv;
  j["max_abs_before_mv"] = r.max_abs_before_mv;
  j["max_abs_after_mv"] = r.explained ? r.max_abs_after_mv : r.max_abs_before_mv;
  j["heldout_before_mv"] = r.heldout_before_mv;
  j["heldout_after_mv"] = r.explained ? r.heldout_after_mv : r.heldout_before_mv;
  j["floor_mv"] = r.floor_mv;
  j["at_floor_before"] = r.at_floor_before;
  j["reason"] = r.reason;
  j["first_step_reason"] = r.selection.reason;
  if (!r.explained && !r.best_partial_effects.empty())
    j["best_partial"] = {{"effects", names_json(r.best_partial_effects)},
                         {"parameters", knobs_json(r.best_partial)},
                         {"heldout_mv", r.best_partial_heldout_mv},
                         {"rmse_mv", r.rmse_after_mv},
                         {"note", "not the answer: it leaves more than 20 % of the held-out residual"}};
  j["candidates"] = candidates_json(r);
  j["selection_steps"] = steps_json(r);
  j["identifiability"] = identifiability_json(r);
  j["score"] = "held-out RMSE in mV (lower is better): parameters fitted on the training samples (one record: "
               "alternate blocks; several records: the other records), error on the others";
  if (!r.excitation_note.empty()) j["excitation_note"] = r.excitation_note;
  j["cases"] = cases_json(r);
  const auto& s = ctx.settings;
  j["cell"] = ctx.cell;
  j["mesh"] = {{"search", {s.search_mesh.n_neg, s.search_mesh.n_r}}, {"final", {s.final_mesh.n_neg, s.final_mesh.n_r}}};
  j["rtol"] = s.rtol;
  j["runs"] = r.runs;
  j["wall_s"] = r.wall_s;
  for (const auto& [k, v] : ctx.extra.items()) j[k] = v;
  return j;
}

namespace {

std::string knob_text(const Hypothesis& h) {
  std::string s;
  for (const auto& k : h)
    s += fmt::format("{}{} = {}", s.empty() ? "" : ", ", parameter_name(k.effect), format_value(k.effect, k.value));
  return s.empty() ? "-" : s;
}

void decision_md(std::ostringstream& md, const DiagnosisResult& r) {
  md << fmt::format("**Diagnosis: `{}`** (explained: {}). {}\n\n", effect_name(r.answer), r.explained ? "yes" : "no",
                    r.reason);
  if (r.explained) {
    md << "| effect / parameter | value | plausibility |\n|---|---|---|\n";
    for (const auto& k : r.model)
      md << fmt::format("| {} | {} | {} |\n", parameter_name(k.effect), format_value(k.effect, k.value),
                        plausibility_note(k.effect, k.value));
    md << "\n";
  } else if (!r.best_partial_effects.empty()) {
    md << fmt::format("Best model reached (not the answer): {} with {}: held-out RMSE {:.3f} mV of {:.3f} mV.\n\n",
                      [&] {
                        std::string s;
                        for (Effect e : r.best_partial_effects) s += (s.empty() ? "" : " + ") + std::string(effect_name(e));
                        return s;
                      }(),
                      knob_text(r.best_partial), r.best_partial_heldout_mv, r.heldout_before_mv);
  }
  md << fmt::format("Floor of this data (voltage noise and the model's numerical error, pooled): {:.3f} mV; the plain "
                    "model's held-out RMSE is {:.1f}x it.\n\n",
                    r.floor_mv, r.floor_mv > 0 ? r.heldout_before_mv / r.floor_mv : 0.0);
  if (!r.excitation_note.empty()) md << "Note on the data: " << r.excitation_note << ".\n\n";
}

void before_after_md(std::ostringstream& md, const DiagnosisResult& r) {
  md << "## Before and fitted model (final mesh)\n\n`fitted` is the best model reached; it is the answer only when "
        "explained.\n\n| data | role | samples | RMSE before mV | RMSE fitted mV | held-out before mV | held-out fitted "
        "mV | max abs before mV | max abs fitted mV |\n|---|---|---|---|---|---|---|---|---|\n";
  for (const auto& c : r.cases)
    md << fmt::format("| {} | {} | {} | {:.3f} | {:.3f} | {:.3f} | {:.3f} | {:.3f} | {:.3f} |\n", c.record->source,
                      c.role, c.record->t_s.size(), c.rmse_before_mv, c.rmse_after_mv, c.heldout_before_mv,
                      c.heldout_after_mv, c.max_abs_before_mv, c.max_abs_after_mv);
  md << fmt::format("| all | | | {:.3f} | {:.3f} | {:.3f} | {:.3f} | {:.3f} | {:.3f} |\n\n", r.rmse_before_mv,
                    r.rmse_after_mv, r.heldout_before_mv, r.heldout_after_mv, r.max_abs_before_mv, r.max_abs_after_mv);
}

void candidates_md(std::ostringstream& md, const DiagnosisResult& r) {
  md << "## Candidates alone (step 1)\n\nScore = held-out RMSE: parameters fitted on the training data (grid + "
        "golden-section search per knob, search mesh), error on the held-out data (final mesh). `none` is the plain "
        "model.\n\n| effect | fitted | runs | training RMSE mV | score (held-out RMSE) mV | RMSE all mV | max abs mV "
        "| note |\n|---|---|---|---|---|---|---|---|\n";
  for (const auto& c : r.candidates) {
    if (!c.available) {
      md << fmt::format("| {} | - | - | - | - | - | - | {} |\n", effect_name(c.effect), c.note);
      continue;
    }
    md << fmt::format("| {} | {} | {} | {:.3f} | {:.3f} | {:.3f} | {:.3f} | {} |\n", effect_name(c.effect),
                      knob_text(c.fitted), c.evaluations, c.train_rmse_mv, c.heldout_rmse_mv, c.rmse_after_mv,
                      c.max_abs_after_mv, c.note);
  }
  md << "\n## Forward selection\n\n| step | with | best addition | held-out RMSE mV | decision |\n|---|---|---|---|---|\n";
  for (std::size_t k = 0; k < r.steps.size(); ++k) {
    const auto& s = r.steps[k];
    std::string base, best = "-";
    for (Effect e : s.base) base += (base.empty() ? "" : " + ") + std::string(effect_name(e));
    double best_mv = HUGE_VAL;
    for (const auto& [e, v] : s.scores)
      if (v < best_mv) {
        best_mv = v;
        best = effect_name(e);
      }
    md << fmt::format("| {} | {} | {} | {} | {} |\n", k + 1, base.empty() ? "-" : base, best,
                      std::isfinite(best_mv) ? fmt::format("{:.3f}", best_mv) : "-", s.reason);
  }
}

void identifiability_md(std::ostringstream& md, const DiagnosisResult& r) {
  if (r.identifiability.empty()) return;
  md << "\n## Sensitivity and identifiability\n\nSensitivity: RMS change of the model voltage per unit of the search "
        "variable (log10 of a factor, else the parameter's unit), at the fitted model. For the fitted knobs, the "
        "Fisher information J^T J / sigma^2 with sigma = the floor gives a standard error (optimistic when the "
        "residual is a model error rather than noise) and the largest correlation with another fitted knob.\n\n"
        "| knob | value | sensitivity mV/unit | fitted | std error % | max abs correlation |\n|---|---|---|---|---|---|\n";
  for (const auto& k : r.identifiability)
    md << fmt::format("| {} | {} | {:.4g} | {} | {} | {} |\n", parameter_name(k.knob), format_value(k.knob, k.value),
                      k.sensitivity_mv, k.selected ? "yes" : "no",
                      k.selected ? fmt::format("{:.3g}", k.relative_std_pct) : "-",
                      k.selected ? fmt::format("{:.3f}", k.max_abs_correlation) : "-");
}

void how_md(std::ostringstream& md) {
  md << "## How it was made\n\n"
        "- The model is the truth DFN driven by the measured current from the record's initial state; residual = "
        "model - measured voltage.\n"
        "- Knobs: model switches (contact resistance, hysteresis, thermal, particle size), drive corrections "
        "(current-sensor offset and gain, start state), factors on the cell's parameters, and measurement structure "
        "applied to the model voltage (voltage-sensor offset and gain, an RC branch, a time skew).\n"
        "- Search runs use a coarse mesh; the plain model's difference between the final and the search mesh is "
        "added to every search run.\n"
        "- One record: alternate blocks train and validate. Several records: each record is scored with the "
        "parameters fitted on the others.\n"
        "- Step 1 chooses a first effect if it cuts the held-out RMSE by 20 % and 0.05 mV, no other leaves "
        "about as much above the floor (within 25 % of it, or half the floor), and (one constant current) no twin "
        "explains it too. Up to two more are added while each "
        "cuts the held-out RMSE by 10 % more.\n"
        "- `explained` only when the held-out RMSE falls to 20 % of the plain model's; `none` when the plain model "
        "is already within 2x the floor; otherwise `unexplained`, with the residual described.\n";
}

}  // namespace

std::vector<std::string> write_report(const std::filesystem::path& dir, const DiagnosisResult& r,
                                      const ReportContext& ctx) {
  std::filesystem::create_directories(dir);
  write_residual_csv(dir / "residual.csv", r);
  std::size_t samples = 0;
  for (const auto& c : r.cases) samples += c.record->t_s.size();
  const PlotOutcome plots = draw_residual_plots(dir, static_cast<int>(r.cases.size()), samples);

  std::ostringstream md;
  md << "# Residual diagnosis\n\nMade by `" << ctx.command_line << "`.\n\n";
  decision_md(md, r);
  before_after_md(md, r);
  candidates_md(md, r);
  identifiability_md(md, r);
  md << "\n## Where the residual is\n\n";
  for (const auto& c : r.cases) {
    md << "### " << c.record->source << "\n\n" << c.excitation.describe() << ".";
    if (!c.record->initial_state_note.empty()) md << " Initial state: " << c.record->initial_state_note << ".";
    md << "\n\nBefore: " << c.adequacy_before.verdict << ".\n\nFitted model: " << c.adequacy_after.verdict << ".\n\n";
    characterisation_md(md, c.char_before, c.char_after);
    md << "\n";
  }
  if (ctx.extra.contains("write_cell")) {
    const auto& w = ctx.extra["write_cell"];
    md << "## The augmented cell (--write-cell)\n\n" << w.value("note", std::string()) << "\n\n";
    for (const auto& a : w.value("effects", nlohmann::json::array())) md << "- " << a.value("line", std::string()) << "\n";
    md << "\n";
  }
  md << "## Plots\n\n";
  if (plots.pngs.empty()) {
    md << "No plots: " << plots.problem << ". The numbers above do not depend on them; residual.csv has the data.\n\n";
  } else {
    for (const auto& p : plots.pngs) md << "![" << p << "](" << p << ")\n\n";
  }
  how_md(md);
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
