#include "diagnosis/diagnose.hpp"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>

#include "diagnosis/minimise.hpp"
#include "io/input_error.hpp"

namespace bms::diagnosis {

namespace {

// Objective value of a parameter for which the solver fails: worse than any real fit.
constexpr double kFailedRunMv = 1e6;

// Where each candidate's parameter is searched. The ranges cover the sizes of models.md
// section 5 several times over; the tolerance is 0.1 % of the range (0.5 % for the
// logarithmic heat-transfer coefficient).
struct SearchSpace {
  double lo, hi, tol;
  bool log10;  // search in log10(value)
  double value(double x) const { return log10 ? std::pow(10.0, x) : x; }
};

SearchSpace search_space(Effect e, double max_abs_current_a) {
  switch (e) {
    case Effect::contact_resistance: return {0.0, 0.02, 2e-5, false};
    case Effect::hysteresis: return {0.0, 0.05, 5e-5, false};
    case Effect::current_offset: {
      const double w = 0.02 * std::max(max_abs_current_a, 0.1);
      return {-w, w, 2e-3 * w, false};
    }
    case Effect::current_gain: return {-0.05, 0.05, 1e-4, false};
    case Effect::thermal: return {-2.5, 1.5, 2e-3, true};  // 3 mW/K (adiabatic-like) .. 30 W/K (isothermal)
    // Log-space spread of the cathode radius; beyond 0.9 the largest of 3 populations is 5x R
    // (25x the diffusion time) and IDA finds no consistent start at 2C.
    case Effect::particle_size: return {0.0, 0.9, 1e-3, false};
    case Effect::none: break;
  }
  return {0.0, 1.0, 1e-3, false};
}

double initial_soc(const CellParameters& cell) {
  const auto& n = cell.negative;
  const double span = n.stoich_max - n.stoich_min;
  return span > 0 ? std::clamp((n.stoich_init - n.stoich_min) / span, 0.0, 1.0) : 1.0;
}

// Pooled sums of squares over several cases.
struct Pool {
  double sum2 = 0.0, max_abs = 0.0;
  std::size_t n = 0;
  void add(const std::vector<double>& r, const std::vector<char>& use) {
    for (std::size_t k = 0; k < r.size(); ++k) {
      if (!use.empty() && !use[k]) continue;
      sum2 += r[k] * r[k];
      max_abs = std::max(max_abs, std::abs(r[k]));
      ++n;
    }
  }
  double rms() const { return n ? std::sqrt(sum2 / static_cast<double>(n)) : 0.0; }
};

std::vector<double> corrected(const std::vector<double>& v, const std::vector<double>& delta) {
  std::vector<double> out(v.size());
  for (std::size_t k = 0; k < v.size(); ++k) out[k] = v[k] + (std::isfinite(delta[k]) ? delta[k] : 0.0);
  return out;
}

bool any(const std::vector<char>& m) { return std::find(m.begin(), m.end(), 1) != m.end(); }

}  // namespace

void split_samples(std::size_t n, int blocks, std::vector<char>& train, std::vector<char>& validate) {
  train.assign(n, 0);
  validate.assign(n, 0);
  const auto b = static_cast<std::size_t>(std::max(2, blocks));
  for (std::size_t k = 0; k < n; ++k) {
    const std::size_t block = k * b / n;
    (block % 2 == 0 ? train : validate)[k] = 1;
  }
}

DiagnosisResult diagnose(const CellParameters& cell, const std::vector<Record>& records,
                         const DiagnoseSettings& settings, const LogFn& log) {
  const auto wall0 = std::chrono::steady_clock::now();
  auto say = [&](const std::string& s) {
    if (log) log(s);
  };
  if (records.empty()) throw InputError("--data: no record given");
  DiagnosisResult out;
  const ModelSetup final_setup{cell, settings.final_mesh, settings.rtol};
  const ModelSetup search_setup{cell, settings.search_mesh, settings.rtol};

  double imax = 0.0;
  bool all_rest = true, all_constant = true;
  for (std::size_t c = 0; c < records.size(); ++c) {
    CaseResult cr;
    cr.record = &records[c];
    cr.excitation = analyse_excitation(records[c]);
    imax = std::max(imax, cr.excitation.max_abs_current_a);
    all_rest = all_rest && cr.excitation.no_current;
    all_constant = all_constant && cr.excitation.constant_current_only;
    const std::size_t n = records[c].t_s.size();
    if (records.size() == 1) {
      split_samples(n, settings.blocks, cr.train, cr.validate);
      cr.role = "train+validate";
    } else {
      cr.train.assign(n, c == 0 ? 1 : 0);
      cr.validate.assign(n, c == 0 ? 0 : 1);
      cr.role = c == 0 ? "train" : "validate";
    }
    cr.soc = state_of_charge(records[c], initial_soc(cell), cell.nominal_capacity_ah > 0 ? cell.nominal_capacity_ah : 1.0);
    say(fmt::format("{}: {} samples over {:.0f} s; {}", records[c].source, n, records[c].duration_s(),
                    cr.excitation.describe()));
    out.cases.push_back(std::move(cr));
  }
  if (all_constant && records.size() > 1) {
    // Several constant-current records separate the effects only if their currents differ.
    const double i0 = out.cases.front().excitation.typical_current_a;
    for (const auto& c : out.cases)
      if (std::abs(c.excitation.typical_current_a - i0) > 0.02 * imax) all_constant = false;
  }
  if (all_constant)
    out.excitation_note =
        "one constant current only: a contact resistance and hysteresis, or a current-sensor offset and gain, "
        "leave the same residual and cannot be told apart";

  // The plain model on the final mesh: "before".
  Pool before_all, before_held;
  for (auto& c : out.cases) {
    say(fmt::format("{}: plain model, mesh {}/{}", c.record->source, settings.final_mesh.n_neg, settings.final_mesh.n_r));
    c.before = run_model(final_setup, *c.record, {});
    c.residual_before_mv = residual_mv(c.before.voltage_v, *c.record);
    c.rmse_before_mv = rms(c.residual_before_mv);
    c.max_abs_before_mv = max_abs(c.residual_before_mv);
    c.char_before = characterise(*c.record, c.residual_before_mv, c.soc);
    before_all.add(c.residual_before_mv, {});
    before_held.add(c.residual_before_mv, c.validate);
    say(fmt::format("{}: RMSE {:.3f} mV, max {:.3f} mV{}", c.record->source, c.rmse_before_mv, c.max_abs_before_mv,
                    c.before.note.empty() ? "" : "; " + c.before.note));
  }
  out.rmse_before_mv = before_all.rms();
  out.max_abs_before_mv = before_all.max_abs;
  out.heldout_before_mv = before_held.rms();

  CandidateResult none;
  none.effect = Effect::none;
  none.heldout_rmse_mv = out.heldout_before_mv;
  none.rmse_after_mv = out.rmse_before_mv;
  none.max_abs_after_mv = out.max_abs_before_mv;
  {
    Pool train;
    for (const auto& c : out.cases) train.add(c.residual_before_mv, c.train);
    none.train_rmse_mv = train.rms();
  }
  for (const auto& c : out.cases) none.voltage_v.push_back(c.before.voltage_v);
  out.candidates.push_back(none);

  if (all_rest) {
    out.selection.reason = "no current flows in the data: no effect can be identified";
  } else {
    // The search mesh's own error is taken out: delta = final - search for the plain model,
    // added to every search-mesh run, so the fit sees the effect, not the mesh.
    std::vector<std::vector<double>> delta(out.cases.size());
    for (std::size_t c = 0; c < out.cases.size(); ++c) {
      if (!any(out.cases[c].train)) continue;
      const auto coarse = run_model(search_setup, *out.cases[c].record, {});
      delta[c].resize(coarse.voltage_v.size());
      for (std::size_t k = 0; k < delta[c].size(); ++k)
        delta[c][k] = out.cases[c].before.voltage_v[k] - coarse.voltage_v[k];
    }
    std::vector<CandidateScore> scores;
    for (Effect e : settings.candidates) {
      CandidateResult cand;
      cand.effect = e;
      cand.available = effect_available(e);
      if (!cand.available) {
        cand.note = "not in this build's truth model";
        say(fmt::format("candidate {}: skipped ({})", effect_name(e), cand.note));
        out.candidates.push_back(cand);
        scores.push_back({e, false, 0.0, 0.0});
        continue;
      }
      const SearchSpace space = search_space(e, imax);
      int failures = 0;
      auto objective = [&](double x) {
        const EffectSetting s{e, space.value(x)};
        Pool train;
        try {
          for (std::size_t c = 0; c < out.cases.size(); ++c) {
            if (!any(out.cases[c].train)) continue;
            const auto run = run_model(search_setup, *out.cases[c].record, s);
            train.add(residual_mv(corrected(run.voltage_v, delta[c]), *out.cases[c].record), out.cases[c].train);
          }
        } catch (const RuntimeFailure&) {
          ++failures;
          return kFailedRunMv;
        }
        const double f = train.rms();
        say(fmt::format("candidate {}: {} = {:.6g}: training RMSE {:.4f} mV", effect_name(e), parameter_name(e),
                        s.value, f));
        return f;
      };
      const auto m = minimise_bounded(objective, space.lo, space.hi, space.tol);
      cand.value = space.value(m.x);
      cand.train_rmse_mv = m.f;
      cand.evaluations = m.evaluations;
      if (failures) cand.note = fmt::format("{} solver failure(s) during the search", failures);
      // Scored on the final mesh: the held-out error is the score, all samples give "after".
      Pool all, held;
      try {
        for (const auto& c : out.cases) {
          const auto run = run_model(final_setup, *c.record, {e, cand.value});
          const auto r = residual_mv(run.voltage_v, *c.record);
          all.add(r, {});
          held.add(r, c.validate);
          cand.voltage_v.push_back(run.voltage_v);
        }
        cand.heldout_rmse_mv = held.rms();
        cand.rmse_after_mv = all.rms();
        cand.max_abs_after_mv = all.max_abs;
      } catch (const RuntimeFailure& err) {
        cand.available = false;
        cand.note = std::string("final run failed: ") + err.what();
      }
      if (cand.available)
        say(fmt::format("candidate {}: {} = {:.6g} after {} runs: held-out RMSE {:.4f} mV (plain {:.4f}), all {:.4f} mV",
                        effect_name(e), parameter_name(e), cand.value, cand.evaluations, cand.heldout_rmse_mv,
                        out.heldout_before_mv, cand.rmse_after_mv));
      else
        say(fmt::format("candidate {}: dropped ({})", effect_name(e), cand.note));
      scores.push_back({e, cand.available, cand.value, cand.heldout_rmse_mv});
      out.candidates.push_back(std::move(cand));
    }
    SelectionRules rules = settings.rules;
    rules.constant_current_only = all_constant;
    out.selection = select_effect(out.heldout_before_mv, scores, rules);
    if (out.selection.effect == Effect::none && !out.excitation_note.empty() &&
        out.selection.reason.find("constant current") == std::string::npos)
      out.selection.reason += " (" + out.excitation_note + ")";
  }

  const CandidateResult* chosen = &out.candidates.front();
  for (const auto& c : out.candidates)
    if (c.effect == out.selection.effect) chosen = &c;
  Pool after_all, after_held;
  for (std::size_t c = 0; c < out.cases.size(); ++c) {
    auto& cr = out.cases[c];
    cr.after = cr.before;
    cr.after.voltage_v = chosen->voltage_v[c];
    cr.residual_after_mv = residual_mv(cr.after.voltage_v, *cr.record);
    cr.rmse_after_mv = rms(cr.residual_after_mv);
    cr.max_abs_after_mv = max_abs(cr.residual_after_mv);
    cr.char_after = characterise(*cr.record, cr.residual_after_mv, cr.soc);
    after_all.add(cr.residual_after_mv, {});
    after_held.add(cr.residual_after_mv, cr.validate);
  }
  out.rmse_after_mv = after_all.rms();
  out.max_abs_after_mv = after_all.max_abs;
  out.heldout_after_mv = after_held.rms();
  out.wall_s = std::chrono::duration<double>(std::chrono::steady_clock::now() - wall0).count();
  say(fmt::format("diagnosis: {} ({})", effect_name(out.selection.effect), out.selection.reason));
  return out;
}

}  // namespace bms::diagnosis
