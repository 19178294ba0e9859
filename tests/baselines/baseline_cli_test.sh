#!/usr/bin/env bash
# Integration test: `bmssim baseline` rejects bad input with exit 2, a one-line message naming
# the option or file, and no summary.json; a valid short file runs (exit 0) and writes the
# columns and keys `bmssim study` reads.
# Usage: baseline_cli_test.sh BMSSIM
set -u
[ "$#" -eq 1 ] && [ -x "$1" ] || { echo "usage: $0 BMSSIM" >&2; exit 2; }
BMSSIM=$1
WORK=$(mktemp -d "${TMPDIR:-/tmp}/bmssim_baseline.XXXXXX") || exit 1
trap 'rm -rf "$WORK"' EXIT
PASSED=0
FAILED=0

# 300 ticks of 2.5 A charge at 0.2 s (the voltage a plausible ramp; only the plumbing is tested).
awk 'BEGIN { print "t_s,cycle,current_meas_a,voltage_meas_v,r_film_ohm_m2";
             for (k = 0; k < 300; k++) printf "%.1f,1,-2.5,%.6f,0.003391\n", 0.2 * k, 3.3 + 1e-5 * k }' > "$WORK/ok.csv"
awk 'NR == 100 { sub(/^[0-9.]+/, "19.85") } { print }' "$WORK/ok.csv" > "$WORK/gap.csv"

expect_bad() {  # NAME PATTERN ARGS...
  local name=$1 pattern=$2
  shift 2
  rm -rf "$WORK/out"
  "$BMSSIM" baseline "$@" --quiet --out "$WORK/out" 2> "$WORK/err"
  local rc=$?
  local first
  first=$(head -n 1 "$WORK/err")
  if [ "$rc" -ne 2 ]; then FAILED=$((FAILED + 1)); echo "not ok - $name: exit $rc, expected 2 ($first)";
  elif ! grep -q -- "$pattern" <<< "$first"; then FAILED=$((FAILED + 1)); echo "not ok - $name: message '$first' lacks '$pattern'";
  elif [ -e "$WORK/out/summary.json" ]; then FAILED=$((FAILED + 1)); echo "not ok - $name: summary.json left behind";
  else PASSED=$((PASSED + 1)); echo "ok - $name"; fi
}

expect_bad missing_file "nothere.csv" --data "$WORK/nothere.csv" --method ekf
expect_bad bad_method "--method" --data "$WORK/ok.csv" --method kalman
expect_bad zero_noise "--noise-v-mv" --data "$WORK/ok.csv" --method crlb --noise-v-mv 0
expect_bad bad_shape "--batch-shape" --data "$WORK/ok.csv" --method batch --batch-shape cubic
expect_bad uneven_time "gap.csv" --data "$WORK/gap.csv" --method batch

rm -rf "$WORK/out"
if "$BMSSIM" baseline --data "$WORK/ok.csv" --method batch --noise-v-mv 0.2 --quiet --out "$WORK/out" 2> "$WORK/err" &&
   head -n 1 "$WORK/out/estimates.csv" | grep -q '^t_s,cycle,mode,r_film_est_ohm_m2,r_film_true_ohm_m2,r_film_sigma_ohm_m2' &&
   grep -q '"crlb_rel_pct"' "$WORK/out/summary.json" && grep -q '"r_film_err_median_pct"' "$WORK/out/summary.json" &&
   grep -q '"wall_s"' "$WORK/out/summary.json"; then
  PASSED=$((PASSED + 1)); echo "ok - valid_run"
else
  FAILED=$((FAILED + 1)); echo "not ok - valid_run: $(head -n 1 "$WORK/err")"
fi
echo "$PASSED passed, $FAILED failed"
[ "$FAILED" -eq 0 ]
