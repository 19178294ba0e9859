#!/usr/bin/env bash
# Integration test: `bmssim diagnose --write-cell DIR` writes the augmented cell, and that cell
# reproduces the record.
#
# Usage: diagnose_write_cell_test.sh BMSSIM
#
# A short record of the NMC template's truth (900 s rest / discharge / rest / charge / rest,
# 0.1 mV voltage noise, truth on a 12-volume mesh at rtol 1e-7: not the diagnosis's own mesh)
# with a known effect: a 3 mohm contact resistance (a model switch: a User-defined key) and a
# cathode exchange current x 0.3 (a re-fit: the BPX field scaled). Each is diagnosed with
# --write-cell; `simulate --cell DIR/cell.bpx.json` on the record's current must then match the
# measured voltage within 2x the diagnosis's floor (noise and numerical error: the contract's
# `none` threshold), where the plain cell is more than 10x the floor away, and must give the
# diagnosis's own fitted RMSE (the file is the model it fitted). `estimate --model reduced` takes
# the cell and its voltage residual z_v falls below 0.8x the plain cell's; `cell-config` takes it. A current-sensor offset is no property of a cell: refused (exit 1, one line
# naming it, no cell.bpx.json). `none` writes nothing unless --write-cell-partial. Bad options
# exit 2 before any model run.
set -u
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
[ "$#" -eq 1 ] && [ -x "$1" ] || { echo "usage: $0 BMSSIM" >&2; exit 2; }
BMSSIM=$(realpath "$1")
WORK=$(mktemp -d "${TMPDIR:-/tmp}/bmssim_write_cell.XXXXXX") || exit 1
trap 'rm -rf "$WORK"' EXIT
cd "$WORK" || exit 1
# shellcheck source=input_error_check.sh
. "$HERE/input_error_check.sh"

PROTOCOL="Rest for 60 seconds; Discharge at 2.5 A for 300 seconds; Rest for 120 seconds; Charge at 2 A for 300 seconds; Rest for 120 seconds"
truth() { # OUT ARGS...
  local out=$1; shift
  "$BMSSIM" simulate --cell nmc --protocol "$PROTOCOL" --dt 1 --noise-v-mv 0.1 --seed 3 --points 12 --radial 12 \
    --rtol 1e-7 --quiet "$@" --out "$out" 2> "err_$out"
}
# RMS (mV) of column COL_A of FILE_A minus column COL_B of FILE_B, row by row (same rows).
rmse_mv() {
  awk -F, -v ca="$2" -v cb="$4" '
    FNR == 1 { for (i = 1; i <= NF; i++) if ($i == (NR == 1 ? ca : cb)) col = i; next }
    NR == FNR { a[FNR] = $col; next }
    { d = 1000 * (a[FNR] - $col); s += d * d; n++ }
    END { if (n == 0) print "nan"; else printf "%.4f\n", sqrt(s / n) }' "$1" "$3"
}
json_number() { # FILE KEY: the top-level number KEY
  python3 -c 'import json, sys; print(json.load(open(sys.argv[1]))[sys.argv[2]])' "$1" "$2"
}

# Bad options: exit 2, one line, before the model runs.
truth truth_c --effect contact_resistance=0.003 || { echo "not ok - truth: $(cat err_truth_c)"; exit 1; }
check_input_error paper_cell 'write-cell.*paper' out_paper -- \
  "$BMSSIM" diagnose --data truth_c/truth.csv --cell paper --write-cell cell_paper --out out_paper --quiet
check_input_error partial_alone 'write-cell-partial.*only with --write-cell' out_partial -- \
  "$BMSSIM" diagnose --data truth_c/truth.csv --cell nmc --write-cell-partial --out out_partial --quiet

# check_cell NAME TRUTH DIAG CELLDIR: the written cell reproduces the record, the plain cell does not.
check_cell() {
  local name=$1 tr=$2 diag=$3 cell=$4
  if [ ! -s "$cell/cell.bpx.json" ] || ! grep -q '"written": true' "$diag/summary.json"; then
    fail "$name" "no cell written: $(grep -o '"note": "[^"]*' "$diag/summary.json" | head -n 1)"; return
  fi
  "$BMSSIM" simulate --cell "$cell/cell.bpx.json" --protocol "csv:$tr/truth.csv" --quiet --out "sim_$name" 2> "err_sim_$name" ||
    { fail "$name" "simulate refused the cell: $(head -n 1 "err_sim_$name")"; return; }
  "$BMSSIM" simulate --cell nmc --protocol "csv:$tr/truth.csv" --quiet --out "plain_$name" 2> /dev/null ||
    { fail "$name" "simulate of the plain cell failed"; return; }
  local aug plain floor fitted
  aug=$(rmse_mv "sim_$name/truth.csv" voltage_v "$tr/truth.csv" voltage_meas_v)
  plain=$(rmse_mv "plain_$name/truth.csv" voltage_v "$tr/truth.csv" voltage_meas_v)
  floor=$(json_number "$diag/summary.json" floor_mv)
  fitted=$(json_number "$diag/summary.json" rmse_after_mv)
  echo "# $name: augmented cell $aug mV, plain cell $plain mV, floor $floor mV, diagnosis fitted $fitted mV"
  if ! awk -v a="$aug" -v p="$plain" -v f="$floor" -v r="$fitted" \
       'BEGIN { exit !(a <= 2 * f && p > 10 * f && a <= 1.05 * r + 0.01 && a >= 0.95 * r - 0.01) }'; then
    fail "$name" "augmented $aug mV (must be <= 2 x floor $floor and the diagnosis's $fitted), plain $plain mV (must be > 10 x floor)"
    return
  fi
  "$BMSSIM" estimate --data "$tr/truth.csv" --cell "$cell/cell.bpx.json" --model reduced --quiet --out "est_$name" \
    > /dev/null 2> "err_est_$name" || { fail "$name" "estimate refused the cell: $(head -n 1 "err_est_$name")"; return; }
  # The firmware's model with the augmented cell: its voltage residual z_v must shrink.
  "$BMSSIM" estimate --data "$tr/truth.csv" --cell nmc --model reduced --quiet --out "estp_$name" > /dev/null 2>&1 ||
    { fail "$name" "estimate of the plain cell failed"; return; }
  local z_aug z_plain
  z_aug=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "z_v") c = i; next } { s += 1e6 * $c * $c; n++ } END { printf "%.4f\n", sqrt(s / n) }' "est_$name/estimates.csv")
  z_plain=$(awk -F, 'NR == 1 { for (i = 1; i <= NF; i++) if ($i == "z_v") c = i; next } { s += 1e6 * $c * $c; n++ } END { printf "%.4f\n", sqrt(s / n) }' "estp_$name/estimates.csv")
  echo "# $name: firmware residual z_v RMS $z_plain mV with the plain cell, $z_aug mV with the augmented one"
  if ! awk -v a="$z_aug" -v p="$z_plain" 'BEGIN { exit !(a < 0.8 * p) }'; then
    fail "$name" "the firmware's residual with the augmented cell $z_aug mV is not below 0.8 x the plain cell's $z_plain mV"; return
  fi
  "$BMSSIM" cell-config --cell "$cell/cell.bpx.json" --out "cfg_$name" > /dev/null 2> "err_cfg_$name" ||
    { fail "$name" "cell-config refused the cell: $(head -n 1 "err_cfg_$name")"; return; }
  pass "$name"
}

# A contact resistance: written as User-defined "Contact resistance [Ohm]".
"$BMSSIM" diagnose --data truth_c/truth.csv --cell nmc --write-cell cell_c --out diag_c --quiet 2> err_diag_c
rc=$?
if [ "$rc" -ne 0 ] || ! grep -q '"effect": "contact_resistance"' diag_c/summary.json; then
  fail contact_resistance "exit $rc, answer $(grep -o '"effect": "[a-z_]*"' diag_c/summary.json 2> /dev/null | head -n 1)"
elif ! grep -q '"Contact resistance \[Ohm\]"' cell_c/cell.bpx.json; then
  fail contact_resistance "no User-defined contact resistance in the cell"
else
  check_cell contact_resistance truth_c diag_c cell_c
fi

# A re-fit of the cell's own parameter: the positive reaction rate constant scaled in BPX.
truth truth_p --set i0_scale_positive=0.3 || fail i0_positive "truth: $(cat err_truth_p)"
"$BMSSIM" diagnose --data truth_p/truth.csv --cell nmc --candidates i0_positive,diffusivity_positive \
  --write-cell cell_p --out diag_p --quiet 2> err_diag_p
rc=$?
if [ "$rc" -ne 0 ] || ! grep -q '"effect": "i0_positive"' diag_p/summary.json; then
  fail i0_positive "exit $rc, answer $(grep -o '"effect": "[a-z_]*"' diag_p/summary.json 2> /dev/null | head -n 1)"
else
  check_cell i0_positive truth_p diag_p cell_p
fi

# A current-sensor offset is not a property of the cell: refused, naming it; the diagnosis is kept.
truth truth_o --effect current_offset=0.05 || fail refused "truth: $(cat err_truth_o)"
"$BMSSIM" diagnose --data truth_o/truth.csv --cell nmc --candidates current_offset,contact_resistance \
  --write-cell cell_o --out diag_o --quiet 2> err_diag_o
rc=$?
if [ "$rc" -ne 1 ]; then
  fail refused "exit code $rc, expected 1 ($(tail -n 1 err_diag_o))"
elif [ "$(wc -l < err_diag_o)" -ne 2 ] || ! grep -q 'write-cell: no cell written: current_offset' err_diag_o; then
  fail refused "stderr does not name current_offset on one line: $(cat err_diag_o)"
elif [ -e cell_o/cell.bpx.json ] || ! grep -q '"written": false' diag_o/summary.json; then
  fail refused "a cell was written, or summary.json does not say it was not"
else
  pass refused
fi

# Nothing to add (`none`): no cell without --write-cell-partial; with it, the input cell as it was.
truth truth_n || fail none "truth: $(cat err_truth_n)"
"$BMSSIM" diagnose --data truth_n/truth.csv --cell nmc --write-cell cell_n --out diag_n --quiet 2> err_diag_n
rc=$?
if [ "$rc" -ne 0 ] || ! grep -q '"effect": "none"' diag_n/summary.json || [ -e cell_n/cell.bpx.json ]; then
  fail none_not_written "exit $rc, answer $(grep -o '"effect": "[a-z_]*"' diag_n/summary.json | head -n 1), cell_n: $(ls cell_n 2>&1)"
else
  pass none_not_written
fi
"$BMSSIM" diagnose --data truth_n/truth.csv --cell nmc --write-cell diag_np --write-cell-partial --out diag_np \
  --quiet 2> err_diag_np
rc=$?
if [ "$rc" -ne 0 ] || [ ! -s diag_np/cell.bpx.json ] || ! grep -q '"from": "best_partial"' diag_np/summary.json; then
  fail none_partial "exit $rc, the cell not written into the --out folder"
elif grep -q '"Contact resistance' diag_np/cell.bpx.json; then
  fail none_partial "an effect was added although the answer is none"
else
  pass none_partial
fi

echo "$PASSED passed, $FAILED failed"
[ "$FAILED" -eq 0 ]
