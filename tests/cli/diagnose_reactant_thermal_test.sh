#!/usr/bin/env bash
# Integration test: a cathode reaction resistance that rises from a knee (resistive reactant) and
# self-heating, two effects that each alone leave most of the residual, are diagnosed together
# across records and written into the augmented cell, which `simulate` then uses.
#
# Usage: diagnose_reactant_thermal_test.sh BMSSIM
#
# Three full discharges (1, 2 and 4 A) of the About:Energy cell's truth with the reactant
# (0.015 ohm m2 below a knee at 0.55, 10^3.7 times that at x = 1) and a lumped heat loss of
# 0.1 W/K, 0.1 mV voltage noise, truth on a 12-volume mesh at rtol 1e-7 (not the diagnosis's
# meshes). `diagnose` on the three records (each scored with the parameters fitted on the other
# two) with the reactant, self-heating and an electrolyte-diffusivity factor as candidates, from
# the best single effects (--open-gain 0), must name the reactant and self-heating together, the
# heat loss within 20 %, and write both into the cell file; `simulate --cell DIR/cell.bpx.json` on
# each record's current must then be within a fifth of the plain cell's RMSE.
set -u
[ "$#" -eq 1 ] && [ -x "$1" ] || { echo "usage: $0 BMSSIM" >&2; exit 2; }
BMSSIM=$(realpath "$1")
. "$(dirname "$(realpath "$0")")/written_cell_check.sh"
WORK=$(mktemp -d "${TMPDIR:-/tmp}/bmssim_reactant_thermal.XXXXXX") || exit 1
trap 'rm -rf "$WORK"' EXIT
cd "$WORK" || exit 1
failures=0
fail() { echo "not ok - $1: $2"; failures=$((failures + 1)); }

discharge_truths "$BMSSIM" 5 --effect resistive_reactant_positive=0.015 --effect resistive_reactant_positive_log10=3.7 \
  --effect resistive_reactant_positive_knee=0.55 --effect thermal=0.1
"$BMSSIM" diagnose --data truth1/truth.csv --data truth2/truth.csv --data truth4/truth.csv --cell aboutenergy \
  --candidates resistive_reactant_positive,thermal,electrolyte_diffusivity --open-gain 0 --write-cell cell \
  --write-cell-partial --out diag --quiet 2> err_diag ||
  { echo "not ok - diagnose: $(head -n 1 err_diag)"; exit 1; }
python3 - diag/summary.json cell/cell.bpx.json <<'PY' || failures=$((failures + 1))
import json, sys
s = json.load(open(sys.argv[1]))
cell = json.load(open(sys.argv[2]))
u = cell["Parameterisation"]["User-defined"]
effects = s["effects"] if s["explained"] else s["best_partial"]["effects"]
p = s["parameters"] if s["explained"] else s["best_partial"]["parameters"]
after = s["heldout_after_mv"] if s["explained"] else s["best_partial"]["heldout_mv"]
print(f"# answer {s['effect']}, effects {effects}, held-out {s['heldout_before_mv']:.3f} -> {after:.3f} mV, {p}")
heat = json.dumps(cell).count("Lumped heat transfer coefficient [W.K-1]") > 0
ok = (sorted(effects) == ["resistive_reactant_positive", "thermal"] and after <= 0.2 * s["heldout_before_mv"]
      and abs(p["thermal_h_w_per_k"] - 0.1) <= 0.02 and heat
      and u["Positive resistive reactant resistance [Ohm.m2]"] == p["resistive_reactant_positive_ohm_m2"])
print("ok - diagnosed together and written" if ok else "not ok - diagnosed together and written")
sys.exit(0 if ok else 1)
PY
written_cell_within_a_fifth "$BMSSIM" 1 2 4
[ "$failures" -eq 0 ] && echo "ok - every record" && exit 0
exit 1
