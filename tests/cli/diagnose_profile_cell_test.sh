#!/usr/bin/env bash
# Integration test: a cathode diffusivity that falls towards full lithiation is diagnosed across
# records and written into the augmented cell, which `simulate` then uses.
#
# Usage: diagnose_profile_cell_test.sh BMSSIM
#
# Three full discharges (1, 2 and 4 A) of the About:Energy cell's truth with the knee profile
# (--effect diffusivity_profile_positive=-1, knee 0.7: D 10x slower at x = 1 than below x = 0.7),
# 0.1 mV voltage noise, truth on a 12-volume mesh at rtol 1e-7 (not the diagnosis's meshes).
# `diagnose` on the three records (each scored with the parameters fitted on the other two) with
# the profile and a constant diffusivity factor as candidates must name the profile, its size
# within 0.2 decades and its knee within 0.05, and write both User-defined keys; `simulate
# --cell DIR/cell.bpx.json` on each record's current must then be within a fifth of the plain
# cell's RMSE against the measured voltage.
set -u
[ "$#" -eq 1 ] && [ -x "$1" ] || { echo "usage: $0 BMSSIM" >&2; exit 2; }
BMSSIM=$(realpath "$1")
. "$(dirname "$(realpath "$0")")/written_cell_check.sh"
WORK=$(mktemp -d "${TMPDIR:-/tmp}/bmssim_profile_cell.XXXXXX") || exit 1
trap 'rm -rf "$WORK"' EXIT
cd "$WORK" || exit 1
failures=0
fail() { echo "not ok - $1: $2"; failures=$((failures + 1)); }

discharge_truths "$BMSSIM" 3 --effect diffusivity_profile_positive=-1 --effect diffusivity_profile_positive_knee=0.7
"$BMSSIM" diagnose --data truth1/truth.csv --data truth2/truth.csv --data truth4/truth.csv --cell aboutenergy \
  --candidates diffusivity_profile_positive,diffusivity_positive --write-cell cell --out diag --quiet 2> err_diag ||
  { echo "not ok - diagnose: $(head -n 1 err_diag)"; exit 1; }
python3 - diag/summary.json cell/cell.bpx.json <<'PY' || failures=$((failures + 1))
import json, sys
s = json.load(open(sys.argv[1]))
u = json.load(open(sys.argv[2]))["Parameterisation"]["User-defined"]
p = s["parameters"]
print(f"# answer {s['effect']}, held-out {s['heldout_before_mv']:.3f} -> {s['heldout_after_mv']:.3f} mV, {p}")
ok = (s["effect"] == "diffusivity_profile_positive" and s["explained"]
      and abs(p["diffusivity_profile_positive_log10"] + 1.0) <= 0.2 and abs(p["diffusivity_profile_positive_knee"] - 0.7) <= 0.05
      and u["Positive diffusivity profile log10 factor at full lithiation [-]"] == p["diffusivity_profile_positive_log10"]
      and u["Positive diffusivity profile knee stoichiometry [-]"] == p["diffusivity_profile_positive_knee"])
print("ok - diagnosed and written" if ok else "not ok - diagnosed and written")
sys.exit(0 if ok else 1)
PY
written_cell_within_a_fifth "$BMSSIM" 1 2 4
[ "$failures" -eq 0 ] && echo "ok - every record" && exit 0
exit 1
