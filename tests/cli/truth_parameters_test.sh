#!/usr/bin/env bash
# Integration test: hidden truth parameters, `bmssim simulate --set NAME=VALUE` and
# `bmssim simulate --list-params` (contract: simulate, "Hidden truth parameters").
#
# Usage: truth_parameters_test.sh BMSSIM SHARED_DIR
#
# --list-params prints the contract's names and needs no --out (a simulation without --out
# still exits 2); bad assignments (unknown name, no '=', not a number, not finite, outside
# the range, a name twice; also through `hil`) exit 2
# with one line naming the parameter and no summary.json; a set initial film resistance is
# the first r_film_ohm_m2 of truth.csv and is recorded in summary.json; nominal values set
# explicitly give the same truth.csv as no --set.
set -u
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
[ "$#" -eq 2 ] && [ -x "$1" ] && [ -d "$2" ] || { echo "usage: $0 BMSSIM SHARED_DIR" >&2; exit 2; }
BMSSIM=$(realpath "$1")
export BMS_SHARED_DIR
BMS_SHARED_DIR=$(realpath "$2")
WORK=$(mktemp -d "${TMPDIR:-/tmp}/bmssim_truth_parameters.XXXXXX") || exit 1
trap 'rm -rf "$WORK"' EXIT
cd "$WORK" || exit 1
# shellcheck source=input_error_check.sh
. "$HERE/input_error_check.sh"

# --list-params: every required name at the start of a line, exit 0, no --out needed.
for cell in paper aboutenergy; do
  if "$BMSSIM" simulate --cell "$cell" --list-params > "list_$cell" 2> "err_list_$cell"; then
    missing=""
    for n in r_film_initial_ohm_m2 film_growth_scale side_i0_scale inventory_scale temperature_k \
             conductivity_scale diffusivity_scale_negative diffusivity_scale_positive; do
      grep -qE "^$n +[-+0-9.e]+ +[^ ]+ +[[(]" "list_$cell" || missing="$missing $n"
    done
    if [ -z "$missing" ]; then pass "list_params_$cell"; else fail "list_params_$cell" "missing:$missing"; fi
  else
    fail "list_params_$cell" "exit code $? ($(head -n 1 "err_list_$cell"))"
  fi
done
grep -qE '^r_film_initial_ohm_m2 +0.003391 +ohm_m2' list_paper && pass "list_params_paper_nominal_film" ||
  fail "list_params_paper_nominal_film" "$(grep r_film list_paper)"

# Without --list-params, --out is still required.
"$BMSSIM" simulate --cell paper --quiet > /dev/null 2> err_no_out
rc=$?
if [ "$rc" -eq 2 ] && grep -q -- "--out" err_no_out; then pass "out_still_required"; else
  fail "out_still_required" "exit code $rc: $(head -n 1 err_no_out)"; fi

expect_bad() { # NAME NEEDLE CELL SET...
  local name=$1 needle=$2 cell=$3; shift 3
  local args=()
  for a in "$@"; do args+=(--set "$a"); done
  check_input_error "$name" "$needle" "$WORK/out_$name" -- "$BMSSIM" simulate --cell "$cell" "${args[@]}" --out "$WORK/out_$name" --quiet
}
expect_bad unknown_name "set 'film_growth'.*unknown.*film_growth_scale" paper film_growth=2
expect_bad no_equals "set.*NAME=VALUE" paper film_growth_scale
expect_bad not_a_number "set.*film_growth_scale=abc.*must be a number" paper film_growth_scale=abc
expect_bad not_finite "set side_i0_scale.*finite" paper side_i0_scale=inf
expect_bad zero_growth "set film_growth_scale=0.*\(0, 100\]" paper film_growth_scale=0
expect_bad hot "set temperature_k=500.*\[233.15, 353.15\] K" paper temperature_k=500
expect_bad big_inventory "set inventory_scale=1.5.*\[0.8, 1.2\]" paper inventory_scale=1.5
expect_bad negative_film "set r_film_initial_ohm_m2=-0.001.*\[0, 1\] ohm_m2" paper r_film_initial_ohm_m2=-0.001
expect_bad twice "set conductivity_scale.*twice" paper conductivity_scale=2 conductivity_scale=3
check_input_error hil_unknown_name "set 'bogus'.*unknown" "$WORK/out_hil" -- \
  "$BMSSIM" hil --set bogus=1 --out "$WORK/out_hil" --quiet

# Two minutes of a 1 A discharge (About:Energy format: current negative on discharge).
awk 'BEGIN { print "Time [s],I[A],U[V]"; for (k = 0; k <= 120; k++) printf "%d,-1.0,3.3\n", k }' > drive.csv
run() { # OUT ARGS...
  local out=$1; shift
  "$BMSSIM" simulate --cell paper --protocol csv:drive.csv --points 8 --radial 8 "$@" --out "$out" --quiet 2> "err_$out"
}
if run plain && run film --set r_film_initial_ohm_m2=0.005 &&
   run nominal --set inventory_scale=1 --set film_growth_scale=1 --set conductivity_scale=1 --set temperature_k=298.15; then
  if python3 - <<'PY'
import csv, json
rows = list(csv.DictReader(open("film/truth.csv")))
assert float(rows[0]["r_film_ohm_m2"]) == 0.005, rows[0]["r_film_ohm_m2"]
assert float(rows[-1]["r_film_ohm_m2"]) > 0.005  # the film grows from there
s = json.load(open("film/summary.json"))
assert s["parameters"]["r_film_initial_ohm_m2"] == 0.005, s["parameters"]
assert s["parameters"]["film_growth_scale"] == 1.0 and s["parameters"]["temperature_k"] == 298.15, s["parameters"]
assert s["options"]["set"] == ["r_film_initial_ohm_m2=0.005"], s["options"]
p = json.load(open("plain/summary.json"))
assert p["options"]["set"] == [] and p["parameters"]["r_film_initial_ohm_m2"] == 0.003391, p["parameters"]
PY
  then pass "set_film_in_truth_and_summary"; else fail "set_film_in_truth_and_summary" "see above"; fi
  if cmp -s plain/truth.csv nominal/truth.csv; then pass "nominal_values_change_nothing"; else
    fail "nominal_values_change_nothing" "truth.csv differs"; fi
else
  fail "valid_runs" "$(cat err_plain err_film err_nominal 2>/dev/null | head -n 2)"
fi

# A BPX cell without side-reaction keys has the paper's side reaction: its initial film (the
# paper's 3.391e-3 ohm m2) is a series resistance in the anode's overpotential, so a larger
# one lowers the voltage at 1 A by (R_set - R_nominal) I / (A a_n L_n); the film grows under
# both, faster with film_growth_scale and side_i0_scale.
run_ae() { # OUT ARGS...
  local out=$1; shift
  "$BMSSIM" simulate --cell aboutenergy --protocol csv:drive.csv --points 8 --radial 8 "$@" --out "$out" --quiet 2> "err_$out"
}
if run_ae ae_plain && run_ae ae_film --set r_film_initial_ohm_m2=0.02 &&
   run_ae ae_fast --set film_growth_scale=2 --set side_i0_scale=3; then
  if python3 - "$BMS_SHARED_DIR/data/aboutenergy-lfp18650/lfp_18650_cell_BPX.json" <<'PY'
import csv, json, sys
n = json.load(open(sys.argv[1]))["Parameterisation"]
area = n["Cell"]["Electrode area [m2]"] * n["Cell"]["Number of electrode pairs connected in parallel to make a cell"]
al = n["Negative electrode"]["Surface area per unit volume [m-1]"] * n["Negative electrode"]["Thickness [m]"]
plain = list(csv.DictReader(open("ae_plain/truth.csv")))
film = list(csv.DictReader(open("ae_film/truth.csv")))
fast = list(csv.DictReader(open("ae_fast/truth.csv")))
r0 = 0.003391
assert float(plain[0]["r_film_ohm_m2"]) == r0 and float(film[0]["r_film_ohm_m2"]) == 0.02
grow_plain = float(plain[-1]["r_film_ohm_m2"]) - r0
grow_fast = float(fast[-1]["r_film_ohm_m2"]) - r0
assert grow_plain > 0, grow_plain
# film_growth_scale x side_i0_scale = 6 on a side current that barely feels the film: ~6x.
assert 5.0 < grow_fast / grow_plain < 6.5, (grow_plain, grow_fast)
drop_mv = 1000 * (float(plain[60]["voltage_v"]) - float(film[60]["voltage_v"]))
expected_mv = 1000 * (0.02 - r0) * float(plain[60]["current_a"]) / (area * al)
assert abs(drop_mv - expected_mv) < 0.05 * expected_mv, (drop_mv, expected_mv)
assert json.load(open("ae_film/summary.json"))["parameters"]["r_film_initial_ohm_m2"] == 0.02
PY
  then pass "set_film_on_bpx_cell"; else fail "set_film_on_bpx_cell" "see above"; fi
else
  fail "valid_bpx_runs" "$(cat err_ae_plain err_ae_film err_ae_fast 2>/dev/null | head -n 2)"
fi

echo "$PASSED passed, $FAILED failed"
[ "$FAILED" -eq 0 ]
