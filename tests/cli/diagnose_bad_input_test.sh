#!/usr/bin/env bash
# Integration test: `bmssim diagnose` on bad or uninformative data.
#
# Usage: diagnose_bad_input_test.sh BMSSIM
#
# Bad input (too short, a gap, time going back, NaN, a missing column, an unknown
# candidate): exit code exactly 2, one line on stderr naming the file (or option) and the
# fault, and no summary.json in --out. Uninformative data (one constant current, with a
# contact resistance injected): exit 0 and the answer `none` with a reason that says why,
# never a guess between the effects that one current cannot separate.
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

make_csv ok.csv 200
expect_bad unknown_candidate 'candidates.*resistence' --data ok.csv --candidates resistence
expect_bad missing_file 'nosuch\.csv' --data nosuch.csv

# One constant current with a real contact resistance in it: contact resistance and
# hysteresis both explain it, so the only honest answer is none, saying why.
awk 'BEGIN { print "Time [s],I[A],U[V]"; for (k = 0; k <= 600; k++) printf "%d,%s,3.3\n", k, (k == 0 ? "0" : "-2.5") }' > cc.csv
if "$BMSSIM" simulate --cell paper --protocol csv:cc.csv --points 6 --radial 6 --effect contact_resistance=0.002 \
     --quiet --out sim_cc 2> err_sim; then
  "$BMSSIM" diagnose --data sim_cc/truth.csv --cell paper --candidates contact_resistance,hysteresis \
    --points 6 --radial 6 --search-points 6 --search-radial 6 --quiet --out diag_cc 2> err_cc >/dev/null
  rc=$?
  if [ "$rc" -ne 0 ]; then
    fail constant_current "exit code $rc: $(head -n 3 err_cc)"
  elif ! grep -q '"effect": "none"' diag_cc/summary.json; then
    fail constant_current "answered $(grep '"effect"' diag_cc/summary.json | head -n 1) instead of none"
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

echo "$PASSED passed, $FAILED failed"
[ "$FAILED" -eq 0 ]
