#!/usr/bin/env bash
# Integration test: the restarted held-out score of `bmssim fit` (and `fit --score-only`).
#
# Usage: fit_score_test.sh BMSSIM
#
# The data: `simulate --cell lco`, 5 cycles of a protocol with a rest after the full charge
# (discharge, rest, CC charge, CV hold to 44 mA, rest 2 min), 1 mV voltage noise and a current
# sensor offset of 8 mA: a model driven by the measured current loses about 0.02 Ah per cycle
# against the cell, as a model run through many cycler cycles drifts with the cycler's count.
# Must show:
# - restarts: `fit --score-only` (the template, the cell that made the data) runs one piece per
#   full charge, each from the measured rest voltage at its end; every held-out cycle scored
#   (coverage 1) with about the same RMSE (no growth over the cycles: max/min < 1.3, each < 15
#   mV); the held-out RMSE is the RMS of fit.csv's scored held-out residuals. Without the
#   restarts the drift accumulates over the cycles and these fail (measured when written).
# - early stops are not scored: a cell with 20 % less electrode area runs empty in the
#   discharges; each stop is listed (cycle, row, why), its rows have no model voltage in fit.csv,
#   coverage = scored / held out < 1, and the RMSE is over the scored rows only.
# - the fit's search restarts where the score does (--train-restarts full-charge, default: more
#   than one search piece) or not (rests: one).
set -u
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
export PYTHONPATH="$HERE${PYTHONPATH:+:$PYTHONPATH}"  # checks.py
[ "$#" -eq 1 ] && [ -x "$1" ] || { echo "usage: $0 BMSSIM" >&2; exit 2; }
BMSSIM=$(realpath "$1")
TEMPLATE="$HERE/../../host_sim/cells/lco.bpx.json"
WORK=$(mktemp -d "${TMPDIR:-/tmp}/bmssim_fit_score.XXXXXX") || exit 1
trap 'rm -rf "$WORK"' EXIT
cd "$WORK" || exit 1
PASSED=0
FAILED=0
pass() { PASSED=$((PASSED + 1)); echo "ok - $1"; }
fail() { FAILED=$((FAILED + 1)); echo "not ok - $1: $2"; }

P="Discharge at 0.873 A for 2 hours or until 3.105 V; Rest for 3 minutes; Charge at 0.873 A for 2 hours or until 4.1 V; Hold at 4.1 V for 2 hours or until 44 mA; Rest for 2 minutes"
"$BMSSIM" simulate --cell lco --protocol "$P" --cycles 5 --dt 10 --noise-v-mv 1 --seed 3 --effect current_offset=0.008 \
  --points 14 --radial 12 --rtol 1e-7 --quiet --out syn || { echo "not ok - simulate failed"; exit 1; }

if "$BMSSIM" fit --data syn/truth.csv --score-only "$TEMPLATE" --train-cycles 1-2 --heldout-cycles 3-5 --out sc \
     2> sc.log; then pass "score-only runs"; else fail "score-only runs" "$(tail -3 sc.log)"; fi
python3 - sc <<'PY' && pass "restarted at every full charge, no drift over the cycles" || fail "restarted score" "see above"
import csv, json, math, sys
d = sys.argv[1]
s = json.load(open(d + "/summary.json"))
from checks import check, passed
check(len(s["pieces"]) == 5, f"one piece per full charge plus the first: {len(s['pieces'])} pieces for 5 cycles")
check(all("rest voltage" in n for n in s["piece_initial_states"][1:]),
      "every restarted piece starts from its measured rest voltage")
check(s["heldout_coverage"] == 1.0 and not s["stops"], f"every held-out row scored (coverage {s['heldout_coverage']})")
held = [c for c in s["cycles"] if c["role"] == "heldout"]
check([c["cycle"] for c in held] == [3, 4, 5], "per-cycle numbers for cycles 3-5")
r = [c["rmse_mv"] for c in held]
print("  held-out RMSE per cycle (mV): " + ", ".join(f"{x:.2f}" for x in r))
check(max(r) < 15, "each held-out cycle under 15 mV")
check(max(r) / min(r) < 1.3, "no growth over the cycles (max/min < 1.3)")
rows = [row for row in csv.DictReader(open(d + "/fit.csv")) if row["role"] == "2" and row["scored"] == "1"]
rms = math.sqrt(sum(float(x["residual_fitted_mv"]) ** 2 for x in rows) / len(rows))
check(abs(rms - s["rmse_heldout_mv"]) < 0.01, f"held-out RMSE {s['rmse_heldout_mv']:.3f} = RMS of fit.csv's scored rows {rms:.3f}")
sys.exit(0 if passed() else 1)
PY
for p in voltage_heldout_cycles.png rmse_cycles.png; do
  [ -s "sc/$p" ] && pass "plot $p" || fail "plot $p" "missing (gnuplot installed?)"
done

# A cell with 20 % less electrode area: it runs empty in every discharge.
python3 - "$TEMPLATE" <<'PY' || { echo "not ok - small cell"; exit 1; }
import json, sys
j = json.load(open(sys.argv[1]))
j["Parameterisation"]["Cell"]["Electrode area [m2]"] *= 0.8
json.dump(j, open("small.bpx.json", "w"), indent=1)
PY
if "$BMSSIM" fit --data syn/truth.csv --score-only small.bpx.json --train-cycles 1-2 --heldout-cycles 3-5 --out small \
     2> small.log; then pass "score-only (small cell) runs"; else fail "score-only (small cell) runs" "$(tail -3 small.log)"; fi
python3 - small <<'PY' && pass "early stops listed, not scored, coverage < 1" || fail "early stops" "see above"
import csv, json, math, sys
d = sys.argv[1]
s = json.load(open(d + "/summary.json"))
from checks import check, passed
check(len(s["stops"]) >= 3, f"{len(s['stops'])} stops listed")
for st in s["stops"]:
    check(all(k in st for k in ("cycle", "row", "rows", "t_s", "why")) and "lower voltage" in st["why"],
          f"stop in cycle {st['cycle']} at row {st['row']} of {st['rows']}: {st['why'][:60]}")
rows = [row for row in csv.DictReader(open(d + "/fit.csv")) if row["role"] == "2"]
scored = [x for x in rows if x["scored"] == "1"]
check(all(x["voltage_fitted_v"] == "nan" for x in rows if x["scored"] == "0"), "no model voltage where not reached")
check(len(rows) == s["heldout_samples"] and len(scored) == s["heldout_scored_samples"], "counts as in fit.csv")
cov = len(scored) / len(rows)
check(0 < cov < 1 and abs(s["heldout_coverage"] - cov) < 1e-12, f"coverage {s['heldout_coverage']:.3f} = scored / held out")
rms = math.sqrt(sum(float(x["residual_fitted_mv"]) ** 2 for x in scored) / len(scored))
check(abs(rms - s["rmse_heldout_mv"]) < 0.01, f"RMSE {s['rmse_heldout_mv']:.2f} mV over the scored rows only ({rms:.2f})")
check(any(c["scored"] < c["samples"] for c in s["cycles"] if c["role"] == "heldout"), "per cycle: scored < samples")
check(any("not scored" in n for n in s["notes"]), "notes say the rows after a stop are not scored")
sys.exit(0 if passed() else 1)
PY

# The fit's search: restarted where the score is, or only at long rests.
for mode in full-charge rests; do
  "$BMSSIM" fit --data syn/truth.csv --template lco --train-cycles 1-2 --heldout-cycles 3-5 --ocp-knots 0 \
    --parameters electrode_area_m2 --max-iterations 2 --train-restarts $mode --quiet --out fit-$mode 2> fit-$mode.log \
    || fail "fit --train-restarts $mode" "$(tail -3 fit-$mode.log)"
done
python3 - <<'PY' && pass "search pieces follow --train-restarts; the score restarts either way" || fail "train restarts" "see above"
import json, sys
a = json.load(open("fit-full-charge/summary.json"))
b = json.load(open("fit-rests/summary.json"))
ok = len(a["search_pieces"]) > 1 and len(b["search_pieces"]) == 1 and len(a["pieces"]) == len(b["pieces"]) == 5
print(f"  search pieces {len(a['search_pieces'])} / {len(b['search_pieces'])}, scoring pieces {len(a['pieces'])} / {len(b['pieces'])}")
print(f"  held out (restarted score): {a['rmse_heldout_mv']:.2f} / {b['rmse_heldout_mv']:.2f} mV")
sys.exit(0 if ok else 1)
PY

echo "# $PASSED passed, $FAILED failed"
[ "$FAILED" -eq 0 ]
