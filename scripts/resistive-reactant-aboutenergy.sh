#!/usr/bin/env bash
# The cathode's resistive reactant on the About:Energy LFP 18650 records (docs/results/diagnosis.md,
# "A resistive reactant"): the truth DFN on each measured current (`simulate --protocol csv:RECORD`,
# mesh 20) with the effect's three knobs (resistance below the knee, its rise in decades to x = 1,
# the knee), alone, with the cathode diffusivity and both exchange-current factors, or with the
# lumped self-heating (`--effect thermal`, its heat-transfer coefficient a knob), fitted by
# Nelder-Mead on the whole-record RMSE of two records and scored on the third (leave one record
# out; every fold starts from the same neutral point, no fold sees its held-out record). Then all
# three records fitted with each knob set (in-sample) and plotted beside the plain DFN.
# A measurement, not a test: about 10 minutes on this machine.
#
# Usage: scripts/resistive-reactant-aboutenergy.sh [OUT_DIR]   (default out/resistive-reactant)
# Environment: BMSSIM=path to use a given binary instead of `./bms sim`; SHARED=path of ../shared;
# ITERS=Nelder-Mead iterations per fit (default 150); KNOB_SETS=the knob sets to fit, separated by
# ';', from "reactant", "reactant + D_pos, i0_pos, i0_neg", "reactant + thermal",
# "reactant + thermal + i0_pos, i0_neg", "reactant + thermal + D_e", "reactant + thermal + Ea" (the
# reactant's activation energy, `--effect resistive_reactant_positive_ea`), "reactant + thermal + psd"
# (the cathode particle-size distribution, `--effect particle_size`), "reactant + thermal, Ea 30 kJ/mol"
# (the activation energy held at a literature value, not fitted) (default the first two).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out=${1:-$root/out/resistive-reactant}
shared=$(cd "${SHARED:-$root/../shared}" && pwd)
data=$shared/data/aboutenergy-lfp18650
if [ -n "${BMSSIM:-}" ]; then sim="$BMSSIM"; else sim="$root/bms sim"; fi
mkdir -p "$out"
/usr/bin/python3 - "$out" "$data" "$sim" "${ITERS:-150}" <<'PY'
import csv, math, os, shlex, shutil, subprocess, sys
out, data, sim, iters = sys.argv[1], sys.argv[2], shlex.split(sys.argv[3]), int(sys.argv[4])
recs = ["1C", "2C", "Co20"]
meas = {r: [float(x["U[V]"]) for x in csv.DictReader(open(f"{data}/LFP_25degC_{r}.csv"))] for r in recs}
factors = {"dp": "diffusivity_scale_positive", "ip": "i0_scale_positive", "in": "i0_scale_negative",
           "de": "electrolyte_diffusivity_scale"}
def decode(x, keys, fixed=None):
    sets, eff = {}, dict(fixed or {})
    for k, v in zip(keys, x):
        if k in factors: sets[factors[k]] = min(max(10 ** v, 0.01), 10.0)
        elif k == "r": eff["resistive_reactant_positive"] = min(10 ** v, 100.0)
        elif k == "s": eff["resistive_reactant_positive_log10"] = min(max(v, 0.0), 6.0)
        elif k == "k": eff["resistive_reactant_positive_knee"] = min(max(v, 0.0), 0.99)
        elif k == "h": eff["thermal"] = min(max(10 ** v, 1e-3), 100.0)
        elif k == "ea": eff["resistive_reactant_positive_ea"] = min(max(1e5 * v, 0.0), 2e5)  # J/mol, 0.3 = 30 kJ/mol
        elif k == "psd": eff["particle_size"] = min(max(v, 0.0), 1.5)  # log-space sigma of the cathode radii
    return sets, eff
def run(r, sets, eff, keep=None):
    d = keep or f"{out}/scratch_{r}"
    shutil.rmtree(d, ignore_errors=True)
    cmd = sim + ["simulate", "--cell", "aboutenergy", "--protocol", f"csv:{data}/LFP_25degC_{r}.csv", "--quiet", "--out", d]
    for k, v in sets.items(): cmd += ["--set", f"{k}={v}"]
    for k, v in eff.items(): cmd += ["--effect", f"{k}={v}"]
    if subprocess.run(cmd, capture_output=True).returncode != 0: return []
    return [float(x["voltage_v"]) for x in csv.DictReader(open(f"{d}/truth.csv"))]
def mse(r, v):  # the model stops at its voltage limit: the rest is scored with its last value (as diagnose does)
    if not v: return float("inf")
    return sum((1e3 * (v[min(i, len(v) - 1)] - m)) ** 2 for i, m in enumerate(meas[r])) / len(meas[r])
def cost(x, keys, rs, fixed):
    sets, eff = decode(x, keys, fixed)
    return math.sqrt(sum(mse(r, run(r, sets, eff)) for r in rs) / len(rs))
def nelder_mead(f, x0, step=0.3):
    n = len(x0)
    pts = [list(x0)] + [[x0[j] + (step if j == i else 0.0) for j in range(n)] for i in range(n)]
    vals = [f(p) for p in pts]
    for _ in range(iters):
        order = sorted(range(n + 1), key=lambda i: vals[i])
        pts, vals = [pts[i] for i in order], [vals[i] for i in order]
        if vals[-1] - vals[0] < 0.05: break
        c = [sum(p[j] for p in pts[:-1]) / n for j in range(n)]
        xr = [c[j] + (c[j] - pts[-1][j]) for j in range(n)]; fr = f(xr)
        if fr < vals[0]:
            xe = [c[j] + 2 * (c[j] - pts[-1][j]) for j in range(n)]; fe = f(xe)
            pts[-1], vals[-1] = (xe, fe) if fe < fr else (xr, fr)
        elif fr < vals[-2]:
            pts[-1], vals[-1] = xr, fr
        else:
            xc = [c[j] + 0.5 * (pts[-1][j] - c[j]) for j in range(n)]; fc = f(xc)
            if fc < vals[-1]:
                pts[-1], vals[-1] = xc, fc
            else:
                for i in range(1, n + 1):
                    pts[i] = [pts[0][j] + 0.5 * (pts[i][j] - pts[0][j]) for j in range(n)]; vals[i] = f(pts[i])
    i = min(range(n + 1), key=lambda i: vals[i])
    return pts[i], vals[i]
plain = {r: math.sqrt(mse(r, run(r, {}, {}))) for r in recs}
pooled = lambda d: math.sqrt(sum(d[r] ** 2 * len(meas[r]) for r in recs) / sum(len(meas[r]) for r in recs))
print(f"plain DFN: " + ", ".join(f"{r} {plain[r]:.1f} mV" for r in recs) + f"; pooled {pooled(plain):.2f} mV")
all_knob_sets = {"reactant": (["r", "s", "k"], [-1.5, 3.0, 0.4]),
                 "reactant + D_pos, i0_pos, i0_neg": (["r", "s", "k", "dp", "ip", "in"], [-1.5, 3.0, 0.4, 0.0, 0.0, 0.0]),
                 "reactant + thermal": (["r", "s", "k", "h"], [-1.5, 3.0, 0.4, -1.0]),
                 "reactant + thermal + i0_pos, i0_neg": (["r", "s", "k", "h", "ip", "in"], [-1.5, 3.0, 0.4, -1.0, 0.0, 0.0]),
                 "reactant + thermal + D_e": (["r", "s", "k", "h", "de"], [-1.5, 3.0, 0.4, -1.0, 0.0]),
                 "reactant + thermal + Ea": (["r", "s", "k", "h", "ea"], [-1.5, 3.0, 0.4, -1.0, 0.3]),
                 "reactant + thermal + psd": (["r", "s", "k", "h", "psd"], [-1.5, 3.0, 0.4, -1.0, 0.3]),
                 "reactant + thermal, Ea 30 kJ/mol": (["r", "s", "k", "h"], [-1.5, 3.0, 0.4, -1.0],
                                                      {"resistive_reactant_positive_ea": 30000.0})}
chosen = os.environ.get("KNOB_SETS", "reactant;reactant + D_pos, i0_pos, i0_neg").split(";")
sets_of_knobs = {name: all_knob_sets[name] for name in chosen}
print("| knobs | held-out record | fitted on | fitted knobs | RMSE fitted records mV | held-out RMSE mV | plain DFN mV |")
print("|---|---|---|---|---|---|---|")
for tag_index, (name, (keys, x0, *rest)) in enumerate(sets_of_knobs.items()):
    fixed = rest[0] if rest else {}
    held = {}
    for h in recs:
        train = [r for r in recs if r != h]
        x, v = nelder_mead(lambda x: cost(x, keys, train, fixed), x0)
        sets, eff = decode(x, keys, fixed)
        held[h] = math.sqrt(mse(h, run(h, sets, eff)))
        knobs = ", ".join(f"{k} {val:.4g}" for k, val in {**eff, **sets}.items())
        print(f"| {name} | {h} | {' + '.join(train)} | {knobs} | {v:.1f} | {held[h]:.1f} | {plain[h]:.1f} |", flush=True)
    print(f"| {name} | pooled | | | | {pooled(held):.2f} | {pooled(plain):.2f} |", flush=True)
    x, v = nelder_mead(lambda x: cost(x, keys, recs, fixed), x0)
    sets, eff = decode(x, keys, fixed)
    tag = f"set{tag_index}"
    fit = {r: run(r, sets, eff, keep=f"{out}/fit_{tag}_{r}") for r in recs}
    print(f"in-sample on all three ({name}): " + ", ".join(f"{r} {math.sqrt(mse(r, fit[r])):.1f} mV" for r in recs) +
          "; " + ", ".join(f"{k} {val:.4g}" for k, val in {**eff, **sets}.items()), flush=True)
plain_runs = {r: run(r, {}, {}, keep=f"{out}/plain_{r}") for r in recs}
for r in recs:
    t = [float(x["Time [s]"]) for x in csv.DictReader(open(f"{data}/LFP_25degC_{r}.csv"))]
    cols = [plain_runs[r]] + [[float(x["voltage_v"]) for x in csv.DictReader(open(f"{out}/fit_set{i}_{r}/truth.csv"))]
                               for i in range(len(sets_of_knobs))]
    with open(f"{out}/curves_{r}.dat", "w") as f:
        f.write("# t_s measured plain " + " | ".join(sets_of_knobs) + " (V)\n")
        for i, m in enumerate(meas[r]):
            f.write(f"{t[i]} {m} " + " ".join(f"{c[min(i, len(c) - 1)]:.5f}" for c in cols) + "\n")
with open(f"{out}/set_names.gp", "w") as f:
    f.write(f"nsets = {len(sets_of_knobs)}\n" + "".join(f'set{i} = "+ {n}"\n' for i, n in enumerate(sets_of_knobs)))
for d in os.listdir(out):
    if d.startswith("scratch_"): shutil.rmtree(f"{out}/{d}")
PY
cat > "$out/plot.gp" <<GP
set terminal pngcairo size 1500,450 font ",10"
set output "$out/resistive_reactant_aboutenergy.png"
load "$out/set_names.gp"
colours = "orange red dark-green"
set multiplot layout 1,3 title "About:Energy LFP 18650 (CC BY-SA 4.0, (c) About:Energy): measured, plain DFN and the resistive reactant (in-sample fits on all three records)"
set xlabel "t (s)"; set ylabel "voltage (V)"; set yrange [2.0:3.6]; set key bottom left
do for [r in "1C 2C Co20"] {
  set title r
  plot "$out/curves_".r.".dat" u 1:2 w l lw 2 lc rgb "black" t "measured", "" u 1:3 w l lc rgb "blue" t "plain DFN", \
       for [i=0:nsets-1] "" u 1:(column(4+i)) w l lc rgb word(colours, i+1) t value(sprintf("set%d", i))
}
unset multiplot
GP
gnuplot "$out/plot.gp"
echo "plot: $out/resistive_reactant_aboutenergy.png"
