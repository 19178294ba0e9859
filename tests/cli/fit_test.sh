#!/usr/bin/env bash
# Integration test: `bmssim fit` recovers a changed parameter of a template.
#
# Usage: fit_test.sh BMSSIM
#
# The data: `simulate --cell lco` with the initial film (series) resistance set to 0.01 ohm m2
# (the template's is 0.003391), 2 CCCV cycles, 1 mV voltage noise, made on a different mesh and
# tolerance (14 volumes per region, 12 per particle, rtol 1e-7) than the fit's search runs (8/8,
# rtol 1e-6): the data are not made by the model that fits them. fit on cycle 1 (the default
# split), cycle 2 held out. Must show: the film resistance fitted, within 3 of its reported sd of
# the value set, the sd positive and under 20 % of the value; RMSE train < 5 mV and held out
# < 8 mV (template's > 8 mV); summary.json with the contract's keys and every parameter's
# value/sd/template; plots; cell.bpx.json accepted by `simulate --cell` and `estimate --cell`.
# The default fit includes the open-circuit correction: here (the template's own OCP) its knots
# must stay within 3 sd + 3 mV of zero.
#
# The open-circuit correction: a truth cell (a BPX file written here) whose positive OCP is the
# template's plus a smooth bump (25 mV, Gaussian in the stoichiometry: not the fit's piecewise-
# linear form) and the film at 0.01 ohm m2, simulated on 14/12 volumes at rtol 1e-7 like the
# first; fit with --ocp-knots 8, every parameter free. Must show: every fitted knot within 3 of its sd plus 3 mV (the
# piecewise-linear form's error for this bump) of the bump at its stoichiometry, the peak found;
# RMSE train < 3 mV, held out < 5 mV (template > 10 mV); the OCP written into cell.bpx.json equals
# the template's plus the reported knots' piecewise-linear function (evaluated here from the
# file's expression); cell.bpx.json accepted by simulate and cell-config (estimate reads the first
# fit's cell, whose knots are written too).
set -u
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
export PYTHONPATH="$HERE${PYTHONPATH:+:$PYTHONPATH}"  # checks.py
# MODE all (default) or ocp: the open-circuit case only (the sanitizer build: the same code paths
# in half the time, the DFN's inner loops run instrumented).
[ "$#" -ge 1 ] && [ "$#" -le 2 ] && [ -x "$1" ] || { echo "usage: $0 BMSSIM [all|ocp]" >&2; exit 2; }
MODE=${2:-all}
BMSSIM=$(realpath "$1")
WORK=$(mktemp -d "${TMPDIR:-/tmp}/bmssim_fit.XXXXXX") || exit 1
trap 'rm -rf "$WORK"' EXIT
cd "$WORK" || exit 1
PASSED=0
FAILED=0
pass() { PASSED=$((PASSED + 1)); echo "ok - $1"; }
fail() { FAILED=$((FAILED + 1)); echo "not ok - $1: $2"; }

if [ "$MODE" = all ]; then
"$BMSSIM" simulate --cell lco --protocol cccv --cycles 2 --current-a 0.873 --cv-end-current-a 0.05 --dt 10 \
  --noise-v-mv 1 --seed 3 --set r_film_initial_ohm_m2=0.01 --points 14 --radial 12 --rtol 1e-7 --quiet --out syn \
  || { echo "not ok - simulate failed"; exit 1; }
if "$BMSSIM" fit --data syn/truth.csv --template lco --out fit 2> fit.log; then pass "fit runs"; else fail "fit runs" "$(tail -3 fit.log)"; fi
grep -q "iteration 1" fit.log && pass "progress on stderr" || fail "progress on stderr" "no iteration lines"

python3 - fit/summary.json <<'PY' && pass "film recovered within 3 sd, RMSE small" || fail "summary" "see above"
import json, math, sys
s = json.load(open(sys.argv[1]))
from checks import check, passed
for k in ("rmse_train_mv", "rmse_heldout_mv", "parameters"):
    check(k in s, "summary has " + k)
for name, p in s["parameters"].items():
    check(all(k in p for k in ("value", "sd", "template")), name + " has value, sd, template")
    check(p["fitted"] or (p["sd"] is None and p["value"] == p["template"] and p.get("note")), name + ": not fitted keeps the template, says why")
f = s["parameters"]["initial_sei_resistance_ohm_m2"]
check(f["fitted"], "the film resistance is fitted")
if f["fitted"]:
    print(f"  film {f['value']:.6g} +- {f['sd']:.3g} ohm m2 (set 0.01, template {f['template']})")
    check(f["sd"] > 0 and f["sd"] < 0.2 * f["value"], "its sd is positive and under 20 %")
    check(abs(f["value"] - 0.01) <= 3 * f["sd"], "within 3 sd of the value set")
print(f"  RMSE train {s['rmse_train_mv']:.2f} mV, held out {s['rmse_heldout_mv']:.2f} mV; template {s['rmse_template_train_mv']:.2f} / {s['rmse_template_heldout_mv']:.2f} mV")
check(s["rmse_train_mv"] < 5, "training RMSE < 5 mV")
check(s["rmse_heldout_mv"] < 8, "held-out RMSE < 8 mV")
check(s["rmse_template_heldout_mv"] > 8, "the template alone is off by more (the data differ from it)")
oc = s["derived"].get("ocp_correction")
check(oc is not None, "the open-circuit correction is fitted by default")
if oc:
    for y, c, sd in zip(oc["positive_stoichiometry"], oc["correction_v"], oc["sd_v"]):
        check(abs(c) <= 3 * (sd or 0) + 3e-3, f"knot at {y:.4f}: {1e3 * c:.2f} mV (sd {sd}) within 3 sd + 3 mV of zero")
sys.exit(0 if passed() else 1)
PY
for p in voltage_train.png voltage_heldout.png residual.png; do
  [ -s "fit/$p" ] && pass "plot $p" || fail "plot $p" "missing (gnuplot installed?)"
done
if "$BMSSIM" simulate --cell fit/cell.bpx.json --protocol "Discharge at 0.5 A for 10 minutes; Rest for 5 minutes" \
     --dt 10 --quiet --out sim-fitted 2> sim.log; then pass "simulate --cell cell.bpx.json"
else fail "simulate --cell cell.bpx.json" "$(tail -2 sim.log)"; fi
if "$BMSSIM" estimate --data syn/truth.csv --cell fit/cell.bpx.json --out est-fitted > est.log 2>&1; then
  pass "estimate --cell cell.bpx.json"
else fail "estimate --cell cell.bpx.json" "$(tail -2 est.log)"; fi
fi

# The open-circuit correction: a truth whose positive OCP is the template's plus a 25 mV bump.
python3 - "$HERE/../../host_sim/cells/lco.bpx.json" <<'PY' || { echo "not ok - truth cell"; exit 1; }
import json, sys
j = json.load(open(sys.argv[1]))
pe = j["Parameterisation"]["Positive electrode"]
pe["OCP [V]"] = "(" + pe["OCP [V]"] + ") + 0.025 * exp(-((x - 0.74) / 0.075) ** 2)"
j["Parameterisation"]["User-defined"]["Initial SEI resistance [Ohm.m2]"] = 0.01
json.dump(j, open("bump.bpx.json", "w"), indent=1)
PY
"$BMSSIM" simulate --cell bump.bpx.json --protocol cccv --cycles 2 --current-a 0.873 --cv-end-current-a 0.05 --dt 10 \
  --noise-v-mv 1 --seed 3 --points 14 --radial 12 --rtol 1e-7 --quiet --out synocp \
  || { echo "not ok - simulate (OCP bump) failed"; exit 1; }
if "$BMSSIM" fit --data synocp/truth.csv --template lco --ocp-knots 8 --out fitocp 2> fitocp.log; then pass "fit --ocp-knots 8 runs"; else fail "fit --ocp-knots 8 runs" "$(tail -3 fitocp.log)"; fi
python3 - fitocp/summary.json fitocp/cell.bpx.json "$HERE/../../host_sim/cells/lco.bpx.json" <<'PY' \
  && pass "OCP bump recovered, written exactly" || fail "OCP correction" "see above"
import json, math, sys
s = json.load(open(sys.argv[1]))
from checks import check, passed
bump = lambda y: 0.025 * math.exp(-((y - 0.74) / 0.075) ** 2)
oc = s["derived"]["ocp_correction"]
ys, cs, sds = oc["positive_stoichiometry"], oc["correction_v"], oc["sd_v"]
check(len(ys) == 8, "8 knots")
for y, c, sd in zip(ys, cs, sds):
    if sd is None:
        check(abs(c) == 0, f"knot at {y:.4f} not fitted, held at 0 (truth {1e3 * bump(y):.2f} mV)")
        continue
    print(f"  knot at {y:.4f}: {1e3 * c:6.2f} +- {1e3 * sd:.2f} mV, truth {1e3 * bump(y):6.2f} mV")
    check(abs(c - bump(y)) <= 3 * sd + 3e-3, "within 3 sd + 3 mV of the truth")
check(max(cs) > 0.015, "the bump's peak found (a knot over 15 mV)")
print(f"  RMSE train {s['rmse_train_mv']:.2f} mV, held out {s['rmse_heldout_mv']:.2f} mV; template {s['rmse_template_train_mv']:.2f} / {s['rmse_template_heldout_mv']:.2f} mV")
check(s["rmse_train_mv"] < 3, "training RMSE < 3 mV")
check(s["rmse_heldout_mv"] < 5, "held-out RMSE < 5 mV")
check(s["rmse_template_heldout_mv"] > 10, "the template alone is off by more than 10 mV")
# The written OCP (a Python expression in BPX) is the template's plus the knots' piecewise-linear function.
env = {"exp": math.exp, "tanh": math.tanh, "abs": abs, "log": math.log, "sqrt": math.sqrt}
written = json.load(open(sys.argv[2]))["Parameterisation"]["Positive electrode"]["OCP [V]"]
template = json.load(open(sys.argv[3]))["Parameterisation"]["Positive electrode"]["OCP [V]"]
def pl(y):
    if y <= ys[0]: return cs[0]
    if y >= ys[-1]: return cs[-1]
    k = max(i for i in range(len(ys) - 1) if ys[i] <= y)
    return cs[k] + (cs[k + 1] - cs[k]) * (y - ys[k]) / (ys[k + 1] - ys[k])
worst = max(abs(eval(written, dict(env, x=y)) - eval(template, dict(env, x=y)) - pl(y))
            for y in [0.3 + 0.0007 * i for i in range(1000)])
check(worst < 1e-9, f"the written OCP = template + correction (worst difference {worst:.2e} V over y 0.3-1.0)")
sys.exit(0 if passed() else 1)
PY
if "$BMSSIM" simulate --cell fitocp/cell.bpx.json --protocol "Discharge at 0.5 A for 10 minutes; Rest for 5 minutes" \
     --dt 10 --quiet --out sim-ocp 2> simocp.log; then pass "simulate --cell (corrected OCP)"
else fail "simulate --cell (corrected OCP)" "$(tail -2 simocp.log)"; fi
# (estimate --cell already read a corrected OCP above in MODE all: the first fit writes its knots too.)
if "$BMSSIM" cell-config --cell fitocp/cell.bpx.json --model-bias-ohm 0 --out cfg-ocp --quiet > cfg.log 2>&1; then
  pass "cell-config --cell (corrected OCP)"
else fail "cell-config --cell (corrected OCP)" "$(tail -2 cfg.log)"; fi

echo "# $PASSED passed, $FAILED failed"
[ "$FAILED" -eq 0 ]
