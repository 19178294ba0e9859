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
set -u
[ "$#" -eq 1 ] && [ -x "$1" ] || { echo "usage: $0 BMSSIM" >&2; exit 2; }
BMSSIM=$(realpath "$1")
WORK=$(mktemp -d "${TMPDIR:-/tmp}/bmssim_fit.XXXXXX") || exit 1
trap 'rm -rf "$WORK"' EXIT
cd "$WORK" || exit 1
PASSED=0
FAILED=0
pass() { PASSED=$((PASSED + 1)); echo "ok - $1"; }
fail() { FAILED=$((FAILED + 1)); echo "not ok - $1: $2"; }

"$BMSSIM" simulate --cell lco --protocol cccv --cycles 2 --current-a 0.873 --cv-end-current-a 0.05 --dt 10 \
  --noise-v-mv 1 --seed 3 --set r_film_initial_ohm_m2=0.01 --points 14 --radial 12 --rtol 1e-7 --quiet --out syn \
  || { echo "not ok - simulate failed"; exit 1; }
if "$BMSSIM" fit --data syn/truth.csv --template lco --out fit 2> fit.log; then pass "fit runs"; else fail "fit runs" "$(tail -3 fit.log)"; fi
grep -q "iteration 1" fit.log && pass "progress on stderr" || fail "progress on stderr" "no iteration lines"

python3 - fit/summary.json <<'PY' && pass "film recovered within 3 sd, RMSE small" || fail "summary" "see above"
import json, math, sys
s = json.load(open(sys.argv[1]))
ok = True
def check(cond, what):
    global ok
    print(("  ok: " if cond else "  FAILED: ") + what)
    ok = ok and cond
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
sys.exit(0 if ok else 1)
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

echo "# $PASSED passed, $FAILED failed"
[ "$FAILED" -eq 0 ]
