#!/usr/bin/env bash
# Integration test: `bmssim fit` refuses bad input at once: exit code 2, one line naming the
# option or file, no summary.json (unknown template, paper template, missing file, a record with
# no current, bad --train-cycles, cycles that hold no data, an unknown --parameters name, an
# --ocp-knots count out of 0 or 2..8, knots asked for in --parameters that --ocp-knots has not, no --template, a bad
# --train-restarts, --score-only with a missing or non-BPX file or with a fitting option).
#
# Usage: fit_bad_input_test.sh BMSSIM
set -u
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
[ "$#" -eq 1 ] && [ -x "$1" ] || { echo "usage: $0 BMSSIM" >&2; exit 2; }
BMSSIM=$(realpath "$1")
WORK=$(mktemp -d "${TMPDIR:-/tmp}/bmssim_fit_bad.XXXXXX") || exit 1
trap 'rm -rf "$WORK"' EXIT
cd "$WORK" || exit 1
# shellcheck source=input_error_check.sh
. "$HERE/input_error_check.sh"
"$BMSSIM" simulate --cell lco --protocol cccv --cycles 1 --current-a 0.873 --dt 30 --quiet --out syn || exit 1
awk 'BEGIN { print "Time [s],I[A],U[V]"; for (k = 0; k < 200; k++) printf "%d,0.0,3.9\n", 10 * k }' > rest.csv

expect_bad() { # NAME NEEDLE ARGS...
  local name=$1 needle=$2; shift 2
  SECONDS=0
  check_input_error "$name" "$needle" "$WORK/out_$name" -- "$BMSSIM" fit "$@" --out "$WORK/out_$name" --quiet
  [ "$SECONDS" -le 5 ] || fail "$name fast" "took $SECONDS s (refused before any model run?)"
}
expect_bad unknown_template '--template.*nosuch' --data syn/truth.csv --template nosuch
expect_bad paper_template '--template paper' --data syn/truth.csv --template paper
expect_bad missing_file '--data.*missing\.csv' --data missing.csv --template lco
expect_bad no_current 'rest\.csv.*no current' --data rest.csv --template lco
expect_bad bad_cycles '--train-cycles' --data syn/truth.csv --template lco --train-cycles 5-x
expect_bad empty_cycles '--train-cycles.*0 training samples' --data syn/truth.csv --template lco --train-cycles 7-9
expect_bad heldout_without_train '--heldout-cycles' --data syn/truth.csv --data syn/truth.csv --template lco --heldout-cycles 2
expect_bad unknown_parameter '--parameters.*nosuch' --data syn/truth.csv --template lco --parameters nosuch
expect_bad bad_rtol '--rtol' --data syn/truth.csv --template lco --rtol 1
expect_bad one_knot '--ocp-knots 1' --data syn/truth.csv --template lco --ocp-knots 1
expect_bad too_many_knots '--ocp-knots 9' --data syn/truth.csv --template lco --ocp-knots 9
expect_bad knots_off_but_asked '--parameters ocp_correction.*--ocp-knots 0' --data syn/truth.csv --template lco \
  --ocp-knots 0 --parameters electrode_area_m2,ocp_correction
expect_bad knot_beyond_count '--parameters ocp_correction_7.*--ocp-knots 6' --data syn/truth.csv --template lco \
  --ocp-knots 6 --parameters ocp_correction_7
expect_bad no_template '--template.*required' --data syn/truth.csv
expect_bad bad_train_restarts '--train-restarts.*often' --data syn/truth.csv --template lco --train-restarts often
expect_bad score_only_missing '--score-only.*nosuch\.bpx\.json' --data syn/truth.csv --score-only nosuch.bpx.json
expect_bad score_only_with_template '--template.*--score-only' --data syn/truth.csv --score-only "$HERE/../../host_sim/cells/lco.bpx.json" \
  --template lco
expect_bad score_only_with_knots '--ocp-knots.*--score-only' --data syn/truth.csv --score-only "$HERE/../../host_sim/cells/lco.bpx.json" \
  --ocp-knots 4
expect_bad score_only_not_bpx '--score-only: rest\.csv' --data syn/truth.csv --score-only rest.csv

echo "# $PASSED passed, $FAILED failed"
[ "$FAILED" -eq 0 ]
