#!/usr/bin/env bash
# Integration test: `bmssim estimate` on a measured file (no truth.csv): a cycler export with
# its own column names, current charge-positive, runs the firmware estimator and reports the
# estimates without errors (summary.json "truth": false, no inventory_err_pct column); a
# measured file without a voltage column or with a bad --current-sign exits 2.
#
# Usage: estimate_measured_test.sh BMSSIM
set -u
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
[ "$#" -eq 1 ] && [ -x "$1" ] || { echo "usage: $0 BMSSIM" >&2; exit 2; }
BMSSIM=$(realpath "$1")
WORK=$(mktemp -d "${TMPDIR:-/tmp}/bmssim_estimate_measured.XXXXXX") || exit 1
trap 'rm -rf "$WORK"' EXIT
cd "$WORK" || exit 1
# shellcheck source=input_error_check.sh
. "$HERE/input_error_check.sh"

# One CCCV cycle of the paper cell, rewritten as a cycler would log it (measured columns only).
if "$BMSSIM" simulate --cell paper --protocol cccv --cycles 1 --dt 1 --points 6 --radial 6 --noise-v-mv 0.2 \
     --quiet --out sim 2> err_sim; then
  awk -F, 'NR == 1 { for (k = 1; k <= NF; k++) col[$k] = k; print "Test_Time(s),Current(A),Voltage(V)"; next }
           { printf "%s,%.6f,%.6f\n", $col["t_s"], -$col["current_meas_a"], $col["voltage_meas_v"] }' \
    sim/truth.csv > measured.csv
  if ! "$BMSSIM" estimate --data measured.csv --cell paper --quiet --out est 2> err_est >/dev/null; then
    fail measured_file "exit code $?: $(head -n 2 err_est)"
  elif ! grep -q '"truth": false' est/summary.json; then
    fail measured_file "summary.json does not say truth: false"
  elif head -n 1 est/estimates.csv | grep -q inventory_err_pct; then
    fail measured_file "an error column without a truth"
  elif [ "$(wc -l < est/estimates.csv)" -lt 1000 ]; then
    fail measured_file "estimates.csv has $(wc -l < est/estimates.csv) lines"
  else
    pass measured_file
  fi
else
  fail measured_file "simulate failed: $(head -n 1 err_sim)"
fi

printf 'Time [s],Current [A]\n0,-1\n1,-1\n2,-1\n' > novoltage.csv
check_input_error missing_voltage 'novoltage\.csv.*no voltage column' "$WORK/out_nv" -- \
  "$BMSSIM" estimate --data novoltage.csv --cell paper --quiet --out "$WORK/out_nv"
check_input_error bad_sign 'current-sign.*sideways' "$WORK/out_bs" -- \
  "$BMSSIM" estimate --data novoltage.csv --cell paper --current-sign sideways --quiet --out "$WORK/out_bs"

echo "$PASSED passed, $FAILED failed"
[ "$FAILED" -eq 0 ]
