#!/usr/bin/env bash
# Integration test: `bmssim estimate --model-effect NAME=VALUE` (RCSI with an effect).
#
# Usage: estimate_model_effect_test.sh BMSSIM
#
# Bad values (unknown name, no '=', not a number, negative resistance, hysteresis beyond
# 0.5 V, gain beyond +-0.5): exit code exactly 2, one line on stderr naming the option, and
# no summary.json. A valid run: summary.json records the effects, and a 1 mohm contact
# resistance lowers the model voltage of a 1 A discharge by 1 mV against the plain model.
set -u
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
[ "$#" -eq 1 ] && [ -x "$1" ] || { echo "usage: $0 BMSSIM" >&2; exit 2; }
BMSSIM=$(realpath "$1")
WORK=$(mktemp -d "${TMPDIR:-/tmp}/bmssim_estimate_effect.XXXXXX") || exit 1
trap 'rm -rf "$WORK"' EXIT
cd "$WORK" || exit 1
# shellcheck source=input_error_check.sh
. "$HERE/input_error_check.sh"

# truth.csv columns the estimator reads: 60 s of a 1 A discharge at 0.2 s.
awk 'BEGIN { print "t_s,current_meas_a,voltage_meas_v"; for (k = 0; k < 300; k++) printf "%.1f,1.0,%.4f\n", 0.2 * k, 3.3 - 0.00001 * k }' > data.csv

expect_bad() { # NAME NEEDLE EFFECT
  local name=$1 needle=$2 effect=$3
  check_input_error "$name" "$needle" "$WORK/out_$name" -- "$BMSSIM" estimate --data data.csv --model-effect "$effect" --out "$WORK/out_$name" --quiet
}

expect_bad unknown_name "model-effect.*thermal.*unknown effect" thermal=0.05
expect_bad no_equals "model-effect.*NAME=VALUE" contact_resistance
expect_bad not_a_number "model-effect.*must be a number" contact_resistance=abc
expect_bad nan_value "model-effect.*finite" current_offset=nan
expect_bad negative_resistance "model-effect contact_resistance.*>= 0" contact_resistance=-0.001
expect_bad huge_hysteresis "model-effect hysteresis.*0.5" hysteresis=0.7
expect_bad huge_gain "model-effect current_gain.*0.5" current_gain=0.6

if "$BMSSIM" estimate --data data.csv --settings paper --out plain --quiet 2> err_plain &&
   "$BMSSIM" estimate --data data.csv --settings paper --model-effect contact_resistance=0.001 --out with --quiet 2> err_with; then
  if python3 - plain with <<'PY'
import csv, json, sys
plain, with_ = sys.argv[1], sys.argv[2]
s = json.load(open(f"{with_}/summary.json"))
assert s["options"]["model_effects"]["contact_resistance_ohm"] == 0.001, s["options"]
assert json.load(open(f"{plain}/summary.json"))["options"]["model_effects"] == {}
a = list(csv.DictReader(open(f"{plain}/estimates.csv")))
b = list(csv.DictReader(open(f"{with_}/estimates.csv")))
assert len(a) == len(b) == 300
for ra, rb in zip(a[1:], b[1:]):
    d = float(rb["model_voltage_v"]) - float(ra["model_voltage_v"])
    assert abs(d + 0.001 * 1.0) < 1e-9, (ra["t_s"], d)
PY
  then pass "contact_resistance_lowers_discharge_voltage"; else fail "contact_resistance_lowers_discharge_voltage" "see above"; fi
else
  fail "valid_runs" "$(cat err_plain err_with 2>/dev/null | head -n 2)"
fi

echo "$PASSED passed, $FAILED failed"
[ "$FAILED" -eq 0 ]
