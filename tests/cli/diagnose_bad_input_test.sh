#!/usr/bin/env bash
# Integration test: `bmssim diagnose` on bad or uninformative data.
#
# Usage: diagnose_bad_input_test.sh BMSSIM
#
# Bad input (too short, a gap, time going back, NaN, a missing column, an unknown
# candidate, a bad --initial-soc or --current-sign): exit code exactly 2, one line on stderr
# naming the file (or option) and the fault, and no summary.json in --out. Uninformative data
# (one constant current, with a contact resistance injected): exit 0 and not a name but
# `unexplained` with a reason that says why, never a guess between the effects that one
# current cannot separate. A UDDS-like drive cycle (1 s samples, peaks up to about 29 A, rests) of
# the paper cell runs through `simulate --protocol csv:` and `diagnose`.
set -u
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
[ "$#" -eq 1 ] && [ -x "$1" ] || { echo "usage: $0 BMSSIM" >&2; exit 2; }
BMSSIM=$(realpath "$1")
WORK=$(mktemp -d "${TMPDIR:-/tmp}/bmssim_diagnose.XXXXXX") || exit 1
trap 'rm -rf "$WORK"' EXIT
cd "$WORK" || exit 1
# shellcheck source=input_error_check.sh
. "$HERE/input_error_check.sh"

# About:Energy format, I negative on discharge; rows 0..N-1 at 1 s, 1 A discharge.
make_csv() { # NAME ROWS [awk filter applied to each data line]
  awk -v n="$2" 'BEGIN { print "Time [s],I[A],U[V]"; for (k = 0; k < n; k++) printf "%d,-1.0,%.4f\n", k, 3.3 - 0.0001 * k }' > "$1"
}

# expect_bad NAME NEEDLE(extended regex, case-insensitive) ARGS...
expect_bad() {
  local name=$1 needle=$2; shift 2
  check_input_error "$name" "$needle" "$WORK/out_$name" -- "$BMSSIM" diagnose "$@" --cell paper --out "$WORK/out_$name" --quiet
}

make_csv short.csv 10
expect_bad too_short 'short\.csv.*too short' --data short.csv

make_csv gap.csv 200
awk -F, 'NR == 1 { print; next } { t = $1; if (t >= 100) t += 3600; print t "," $2 "," $3 }' gap.csv > gap2.csv
expect_bad gap 'gap2\.csv.*gap' --data gap2.csv

make_csv back.csv 200
awk -F, 'NR == 1 { print; next } { t = $1; if (NR == 120) t = 50; print t "," $2 "," $3 }' back.csv > back2.csv
expect_bad time_goes_back 'back2\.csv.*time' --data back2.csv

make_csv nan.csv 200
awk -F, 'NR == 1 { print; next } { v = $3; if (NR == 77) v = "nan"; print $1 "," $2 "," v }' nan.csv > nan2.csv
expect_bad nan 'nan2\.csv.*line 77' --data nan2.csv

make_csv col.csv 200
cut -d, -f1,2 col.csv > col2.csv
expect_bad missing_voltage 'col2\.csv.*U\[V\]' --data col2.csv

printf 'Time [s],Voltage [V],Temp [degC]\n0,3.3,25\n1,3.3,25\n' > nocurrent.csv
expect_bad missing_current 'nocurrent\.csv.*no current column' --data nocurrent.csv

make_csv ok.csv 200
expect_bad bad_initial_soc 'initial-soc.*1\.5' --data ok.csv --initial-soc 1.5
expect_bad bad_current_sign 'current-sign.*upwards' --data ok.csv --current-sign upwards
expect_bad unknown_candidate 'candidates.*resistence' --data ok.csv --candidates resistence
expect_bad missing_file 'nosuch\.csv' --data nosuch.csv

# One constant current with a real contact resistance in it: contact resistance and
# hysteresis both explain it, so the only honest answer names neither, saying why.
awk 'BEGIN { print "Time [s],I[A],U[V]"; for (k = 0; k <= 600; k++) printf "%d,%s,3.3\n", k, (k == 0 ? "0" : "-2.5") }' > cc.csv
if "$BMSSIM" simulate --cell paper --protocol csv:cc.csv --points 6 --radial 6 --effect contact_resistance=0.002 \
     --quiet --out sim_cc 2> err_sim; then
  "$BMSSIM" diagnose --data sim_cc/truth.csv --cell paper --candidates contact_resistance,hysteresis \
    --points 6 --radial 6 --search-points 6 --search-radial 6 --quiet --out diag_cc 2> err_cc >/dev/null
  rc=$?
  if [ "$rc" -ne 0 ]; then
    fail constant_current "exit code $rc: $(head -n 3 err_cc)"
  elif ! grep -q '"effect": "unexplained"' diag_cc/summary.json || ! grep -q '"explained": false' diag_cc/summary.json; then
    fail constant_current "answered $(grep '"effect"' diag_cc/summary.json | head -n 1) instead of unexplained"
  elif ! grep -qi 'constant current' diag_cc/summary.json || ! grep -qi 'constant current' err_cc; then
    fail constant_current "the reason does not say 'constant current' (stderr: $(cat err_cc))"
  elif [ ! -s diag_cc/report.md ] || [ ! -s diag_cc/residual.csv ]; then
    fail constant_current "report.md or residual.csv missing"
  else
    pass constant_current
  fi
else
  fail constant_current "simulate failed: $(head -n 1 err_sim)"
fi

# A UDDS-like drive cycle: micro-trips (accelerate, cruise, brake with regeneration, stop),
# 1 s samples, peaks up to about 29 A (measured: 28.7 A), in a cycler's own column names, charge-positive.
awk 'BEGIN {
  srand(7); print "Time (s),Current (A),Voltage (V)"; t = 0
  for (k = 0; k < 30; k++) printf "%d,0,3.3\n", t++
  while (t < 900) {
    vmax = 8 + 17 * rand(); acc = 0.8 + 0.7 * rand(); v = 0
    while (v < vmax) { v += acc; if (v > vmax) v = vmax; printf "%d,%.4f,3.3\n", t++, -(0.9 * v * acc + 0.5) }
    n = 10 + int(40 * rand()); for (k = 0; k < n; k++) printf "%d,%.4f,3.3\n", t++, -(0.025 * v * v + 0.8)
    while (v > 0) { d = 0.8 + 0.6 * rand(); v -= d; if (v < 0) v = 0; printf "%d,%.4f,3.3\n", t++, 0.6 * v * d }
    n = 5 + int(30 * rand()); for (k = 0; k < n; k++) printf "%d,0,3.3\n", t++
  } }' > udds.csv
if "$BMSSIM" simulate --cell paper --protocol csv:udds.csv --points 8 --radial 8 --noise-v-mv 0.1 --quiet \
     --out sim_udds 2> err_udds_sim; then
  if "$BMSSIM" diagnose --data sim_udds/truth.csv --cell paper --candidates listed --points 8 --radial 8 \
       --search-points 5 --search-radial 5 --quiet --out diag_udds 2> err_udds >/dev/null &&
     grep -q '"effect"' diag_udds/summary.json; then
    pass udds_drive_cycle
  else
    fail udds_drive_cycle "diagnose failed: $(tail -n 2 err_udds)"
  fi
else
  fail udds_drive_cycle "simulate failed: $(tail -n 2 err_udds_sim)"
fi

echo "$PASSED passed, $FAILED failed"
[ "$FAILED" -eq 0 ]
