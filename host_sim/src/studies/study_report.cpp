#include "studies/study_report.hpp"

#include <cmath>
#include <cstring>
#include <map>
#include <fmt/format.h>

#include "io/gnuplot.hpp"
#include "sim/truth_output.hpp"

namespace bms::study {

namespace fs = std::filesystem;
using nlohmann::json;

namespace {

// gnuplot single-quoted strings double a quote to keep it.
std::string gp_quote(const std::string& text) {
  std::string q;
  for (char ch : text) q += ch == '\'' ? std::string("''") : std::string(1, ch);
  return q;
}

std::string gnuplot_script(const FigureData& f, const fs::path& dir) {
  std::string s = "set terminal pngcairo size 1100,650 noenhanced\n";
  s += fmt::format("set output '{}'\n", (dir / (f.id + ".png")).string());
  s += fmt::format("set title '{}'\nset xlabel '{}'\nset ylabel '{}'\nset grid\nset key outside right\n", gp_quote(f.title),
                   gp_quote(f.xlabel), gp_quote(f.ylabel));
  if (f.y_min < f.y_max) s += fmt::format("set yrange [{}:{}]\n", f.y_min, f.y_max);
  s += "plot ";
  for (std::size_t i = 0; i < f.curves.size(); ++i) {
    const auto& c = f.curves[i];
    s += fmt::format("{}'{}' index {} using {}:{} with {} lw 1.5 title '{}'", i ? ", \\\n     " : "",
                     (dir / (f.id + ".dat")).string(), c.block, c.x_col, c.y_col, f.style, gp_quote(c.legend));
  }
  return s + "\n";
}

std::string pct(const json& j, const char* key = "mean") {
  if (!j.is_object() || !j.contains(key) || !j[key].is_number()) return "-";
  const double v = j[key].get<double>();
  return std::isfinite(v) ? fmt::format("{:.3g}", v) : "-";
}

std::string num(const json& j) {
  if (!j.is_number()) return "-";
  const double v = j.get<double>();
  return std::isfinite(v) ? fmt::format("{:.3g}", v) : "-";
}

// Arms in a stable order: the estimator arms first, then the baselines.
std::vector<std::string> arm_names(const json& s) {
  std::vector<std::string> out;
  const json nf = s.value("noise_free", json::object());
  for (const char* a : {"full-paper", "full-best", "reduced-paper", "reduced-best", "reduced-beyond", "ekf", "batch", "crlb"}) {
    bool seen = nf.contains(a);
    for (const auto& l : s.value("noise", json::array())) seen = seen || l["arms"].contains(a);
    if (seen) out.push_back(a);
  }
  return out;
}

// What the paper says about each figure (quoted from the paper's text).
const char* paper_statement(const std::string& id) {
  if (id == "fig08") return "\"The film resistance increases by about 1.5%, while the voltage changes by about 0.1-0.2 mV.\"";
  if (id == "fig09") return "\"an output measurement noise with standard deviation of 0.02 mV is small enough for an accurate identification.\"";
  if (id == "fig10") return "\"the algorithm can still estimate the film resistance within 1.5% of its true value.\" (sigma = 0.2 mV)";
  if (id == "fig11") return "\"When applied current is 2.495 A, whose difference from 2.50 A is 5 mA, the difference of output voltage is on the order of 0.1 mV\"";
  if (id == "fig12") return "\"RCSI can provide an accurate identification with this level of input measurement noise.\" (sigma = 0.5 mA)";
  if (id == "fig13") return "\"to estimate the film resistance within 1.5% of its true value, the standard deviation of the input measurement noise should not exceed 5 mA.\"";
  if (id == "fig14") return "\"This figure shows a slight error in the output voltage when the initial conditions are perturbed by +-1%.\"";
  if (id == "fig15") return "\"A 1% error in the initialization causes a 7% change in the identified film resistance.\"";
  if (id == "fig16") return "\"The true film resistance changes by only 0.004% for a 1% change in the initial conditions.\"";
  if (id == "fig17") return "\"The order of magnitude of the change in output voltage is 0.1 mV.\"";
  return "";
}

// Our number for the same statement, from summary.json.
std::string our_statement(const std::string& id, const json& s) {
  std::string out;
  if (id == "fig08" && s.contains("fig08")) {
    out = "Film growth per cycle (%): ";
    for (const auto& g : s["fig08"]["film_growth_per_cycle_pct"]) out += num(g) + " ";
    out += "; median |voltage change| between successive cycles in CC charge (mV): ";
    for (const auto& p : s["fig08"]["pairs"]) out += num(p["dv_median_abs_mv"]) + " ";
    return out;
  }
  if (id == "fig11" && s.contains("fig11")) {
    for (const auto& c : s["fig11"]["currents"])
      out += fmt::format("{} A: median |dV| {} mV (max {}); ", c["current_a"].get<double>(), num(c["dv_median_abs_mv"]),
                         num(c["dv_max_abs_mv"]));
    return out;
  }
  const std::map<std::string, std::string> level_of = {
      {"fig09", "v0.02mV"}, {"fig10", "v0.2mV"}, {"fig12", "i0.5mA"}, {"fig13", "i5mA"}};
  if (level_of.count(id)) {
    for (const auto& l : s.value("noise", json::array())) {
      if (l["level"] != level_of.at(id)) continue;
      out = fmt::format("Over {} seeds, worst-cycle median error, mean (std) per arm: ", l["seeds"].get<int>());
      for (const auto& [arm, a] : l["arms"].items())
        out += fmt::format("{} {} % ({}); ", arm, pct(a["err_worst_cycle_pct"]), pct(a["err_worst_cycle_pct"], "std"));
    }
    return out;
  }
  const json ic = s.value("ic", json::object());
  if (id == "fig14" && ic.contains("output_error")) {
    for (const auto& [arm, per] : ic["output_error"].items())
      for (const auto& [k, v] : per.items()) out += fmt::format("{} IC {} %: median z {} mV; ", arm, k, num(v["z_median_mv"]));
    return out;
  }
  if (id == "fig15" && ic.contains("identified_r_film_change")) {
    for (const auto& [arm, per] : ic["identified_r_film_change"].items())
      out += fmt::format("{}: change in cycle 1 up to {} %; ", arm, num(per["cycle1_change_max_pct"]));
    return out;
  }
  if ((id == "fig16" || id == "fig17") && ic.contains("true")) {
    if (id == "fig16")
      return fmt::format("Largest change in cycle 1's CC charge (same time since its start): {} %; at the cycle "
                         "ends (cycle-aligned, growing over the cycles): up to {} %",
                         num(ic["true"]["cycle1_cc_charge_r_film_change_max_abs_pct"]),
                         num(ic["true"]["r_film_change_at_cycle_ends_max_abs_pct"]));
    for (const auto& [k, v] : ic["true"].items())
      if (v.is_object()) out += fmt::format("IC {} %: median |dV| {} mV (max {}); ", k, num(v["cycle1_cc_charge_dv_median_abs_mv"]),
                                            num(v["cycle1_cc_charge_dv_max_abs_mv"]));
    return out;
  }
  return out;
}

}  // namespace

int draw_figures(const fs::path& out_dir, const Collected& c) {
  const fs::path dir = out_dir / "figures";
  int drawn = 0;
  GnuplotOptions gnuplot;
  gnuplot.log = dir / "gnuplot.log";
  for (const auto& f : c.figures) {
    const fs::path gp = dir / (f.id + ".gp");
    write_file_atomically(gp, gnuplot_script(f, dir));
    const int rc = run_gnuplot(gp, gnuplot);
    if (rc == kGnuplotMissing) return 0;
    if (rc == 0 && fs::exists(dir / (f.id + ".png"))) ++drawn;
  }
  return drawn;
}

std::string headline_table(const json& s) {
  const auto arms = arm_names(s);
  std::string t = "| paper's result | paper |";
  for (const auto& a : arms) t += " " + a + " |";
  t += "\n|---|---|";
  for (std::size_t i = 0; i < arms.size(); ++i) t += "---|";
  t += "\n";
  const std::map<std::string, std::pair<std::string, std::string>> rows = {
      {"v0.02mV", {"film-resistance error, sigma_v = 0.02 mV", "\"accurate\""}},
      {"v0.2mV", {"film-resistance error, sigma_v = 0.2 mV", "within 1.5 %"}},
      {"i0.5mA", {"film-resistance error, sigma_i = 0.5 mA", "\"accurate\""}},
      {"i5mA", {"film-resistance error, sigma_i = 5 mA", "within 1.5 %"}}};
  t += "| film-resistance error, no noise (worst cycle) | - |";
  for (const auto& a : arms) t += " " + num(s["noise_free"].value(a, json::object()).value("worst_cycle_pct", json())) + " % |";
  t += "\n";
  for (const char* level : {"v0.02mV", "v0.2mV", "i0.5mA", "i5mA"}) {
    for (const auto& l : s.value("noise", json::array())) {
      if (l["level"] != level) continue;
      t += fmt::format("| {} (worst cycle, mean +- std over up to {} seeds; [noise's own share]) | {} |",
                       rows.at(level).first, l["seeds"].get<int>(), rows.at(level).second);
      for (const auto& a : arms) {
        if (!l["arms"].contains(a)) {
          t += " - |";
          continue;
        }
        const json& x = l["arms"][a];
        const json& w = x["err_worst_cycle_pct"];
        const std::string value = w.value("n", 0) > 1 ? pct(w) + " +- " + pct(w, "std") + " %" : pct(w) + " % (1 seed)";
        t += fmt::format(" {} [{} %] |", value, pct(x["dev_from_noise_free_rms_pct"]));
      }
      t += "\n";
    }
  }
  const json ic = s.value("ic", json::object());
  t += "| change of identified R_film for +-1 % initial-condition error (cycle 1 / worst of all cycles) | 7 % |";
  for (const auto& a : arms) {
    const json id = ic.value("identified_r_film_change", json::object());
    t += id.contains(a) ? " " + num(id[a]["cycle1_change_max_pct"]) + " % / " +
                              num(id[a].value("worst_cycle_change_max_pct", json())) + " % |"
                        : " - |";
  }
  t += "\n| change of true R_film for +-1 % initial conditions (cycle 1 CC charge; at cycle ends in brackets) | 0.004 % |";
  const std::string tr = ic.contains("true") ? num(ic["true"]["cycle1_cc_charge_r_film_change_max_abs_pct"]) + " % (" +
                                                   num(ic["true"]["r_film_change_at_cycle_ends_max_abs_pct"]) + " %) (truth)"
                                             : "-";
  for (std::size_t i = 0; i < arms.size(); ++i) t += " " + (i == 0 ? tr : std::string("")) + " |";
  if (arms.empty()) t += " " + tr + " |";
  return t + "\n";
}

void write_report(const fs::path& out_dir, const Collected& c, int drawn, const std::string& command) {
  std::string r = "# The paper's sensitivity studies, reproduced\n\n";
  r += "Made by: `" + command + "`\n\n";
  r += "Error = median over a cycle's constant-current charge of |R_film estimated - true| / true; \"worst "
       "cycle\" = the largest of the per-cycle values; \"noise's own share\" = RMS over CC charge of the "
       "deviation from the same arm on noise-free data, relative to the true R_film. Arms: reduced-* = "
       "firmware estimator with the firmware's reduced model, full-* = with the full DFN (the paper's "
       "setting); *-paper = the paper's RCSI settings, *-best = `estimate --settings best` (the film, its growth gain and the lithium inventory identified together, from the nominal cell only), reduced-beyond = `estimate --settings nominal-growth` (RCSI plus state re-synchronisation, bias calibration and the nominal growth law); ekf / batch = augmented-state EKF and per-cycle batch least squares on the reduced model, crlb = Cramer-Rao bound (its column is the bound itself, not an error).\n\n";
  r += headline_table(c.summary) + "\n";
  if (!c.missing.empty()) {
    r += fmt::format("Steps without output ({}; not in the numbers): ", c.missing.size());
    for (std::size_t i = 0; i < c.missing.size() && i < 20; ++i) r += (i ? ", " : "") + c.missing[i];
    r += c.missing.size() > 20 ? ", ...\n\n" : "\n\n";
  }
  if (drawn == 0 && !c.figures.empty())
    r += "gnuplot was not found or failed: the figures' data and scripts are in figures/*.dat and *.gp "
         "(`gnuplot figures/fig08.gp` draws one).\n\n";
  for (const auto& f : c.figures) {
    r += fmt::format("## Figure {}\n\n", std::stoi(f.id.substr(3)));
    r += fmt::format("Paper: {}\n\nOurs: {}\n\n", paper_statement(f.id), our_statement(f.id, c.summary));
    r += fmt::format("![{}](figures/{}.png)\n\n", f.title, f.id);
  }
  write_file_atomically(out_dir / "report.md", r);
}

}  // namespace bms::study
