#!/usr/bin/env bash
# Integration test: real files read right or refused, and the user's data never touched.
# Each case asserts the exit code and the field named (or the numbers); one case per kind of
# input that was read silently wrong before (docs/results/reliability.md lists them).
#
# Usage: measured_inputs_test.sh BMSSIM [SHARED_DIR]
set -u
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
[ "$#" -ge 1 ] && [ -x "$1" ] || { echo "usage: $0 BMSSIM [SHARED_DIR]" >&2; exit 2; }
BMSSIM=$(realpath "$1")
SHARED=${2:-}
WORK=$(mktemp -d "${TMPDIR:-/tmp}/bmssim_measured_inputs.XXXXXX") || exit 1
trap 'rm -rf "$WORK"' EXIT
cd "$WORK" || exit 1
# shellcheck source=input_error_check.sh
. "$HERE/input_error_check.sh"

# Two CCCV cycles of the paper cell at 1 s, rewritten as a cycler logs them (discharge
# negative, PyBaMM's header) at 1, 30, 60 and 120 s.
"$BMSSIM" simulate --cell paper --protocol cccv --cycles 2 --dt 1 --points 6 --radial 6 --noise-v-mv 0.2 \
  --quiet --out sim 2> err_sim >/dev/null || { echo "simulate failed: $(head -n 1 err_sim)"; exit 1; }
for s in 1 30 60 120; do
  awk -F, -v s="$s" 'NR == 1 { for (k = 1; k <= NF; k++) col[$k] = k; print "Time [s],Current [A],Voltage [V]"; next }
    ($col["t_s"] % s) == 0 { printf "%s,%.6f,%.6f\n", $col["t_s"], -$col["current_meas_a"], $col["voltage_meas_v"] }' \
    sim/truth.csv > "m$s.csv"
done
final_film() { tail -n 1 "$1/estimates.csv" | awk -F, '{ print $5 }'; }

# --- 1. Coarse sampling: a model step per sample with the firmware's catch-up of the ticks
# between samples; the film stays physical and close to the 1 s record's.
if "$BMSSIM" estimate --data m1.csv --cell paper --quiet --out e1 2> err_e1 >/dev/null; then
  ref=$(final_film e1)
  for s in 30 60; do
    if ! "$BMSSIM" estimate --data "m$s.csv" --cell paper --quiet --out "e$s" 2> "err_e$s" >/dev/null; then
      fail "sampled_${s}s" "exit code $?: $(head -n 1 "err_e$s")"
      continue
    fi
    film=$(final_film "e$s")
    rows=$(($(wc -l < "e$s/estimates.csv") - 1))
    dev=$(awk -v a="$film" -v b="$ref" 'BEGIN { printf "%.2f", (a - b) / b * 100 }')
    if awk -v a="$film" -v b="$ref" 'BEGIN { exit !(a > 0 && (a - b) / b < 0.05 && (b - a) / b < 0.05) }' &&
       [ "$rows" -eq $(($(wc -l < "m$s.csv") - 1)) ]; then
      pass "sampled_${s}s (final film $film vs $ref at 1 s: $dev %, $rows rows)"
    else
      fail "sampled_${s}s" "final film $film vs $ref at 1 s ($dev %), $rows rows"
    fi
  done
else
  fail sampled_1s "exit code $?: $(head -n 1 err_e1)"
fi
check_input_error sampled_120s 'm120\.csv.*every 120 s.*60 s' e120 -- \
  "$BMSSIM" estimate --data m120.csv --cell paper --quiet --out e120

# --- 2. The current sign: settled by the layout, --current-sign, or the data. A discharge-
# positive file under a cycler-style header contradicts the voltage's response: refused
# naming the option by every command that reads it; with the option it runs.
awk -F, 'NR == 1 { for (k = 1; k <= NF; k++) col[$k] = k; print "Time [s],Current [A],Voltage [V]"; next }
  { printf "%s,%.6f,%.6f\n", $col["t_s"], $col["current_meas_a"], $col["voltage_meas_v"] }' sim/truth.csv > dpos.csv
check_input_error sign_estimate 'dpos\.csv.*contradicts the voltage.*--current-sign discharge-positive' sign_e -- \
  "$BMSSIM" estimate --data dpos.csv --cell paper --quiet --out sign_e
check_input_error sign_simulate 'dpos\.csv.*contradicts the voltage.*--current-sign discharge-positive' sign_s -- \
  "$BMSSIM" simulate --protocol csv:dpos.csv --quiet --out sign_s
check_input_error sign_diagnose 'dpos\.csv.*contradicts the voltage.*--current-sign discharge-positive' sign_d -- \
  "$BMSSIM" diagnose --data dpos.csv --cell paper --out sign_d
check_input_error sign_simulate_unused '--current-sign: only with --protocol csv' sign_u -- \
  "$BMSSIM" simulate --current-sign charge-positive --quiet --out sign_u
if "$BMSSIM" estimate --data dpos.csv --cell paper --current-sign discharge-positive --quiet --out sign_ok 2>err_sign >/dev/null; then
  film=$(final_film sign_ok)
  if awk -v a="$film" -v b="$(final_film e1)" 'BEGIN { exit !((a - b) / b < 0.001 && (b - a) / b < 0.001) }'; then
    pass "sign_option (film $film, as the charge-positive file's)"
  else fail sign_option "film $film, the charge-positive file gives $(final_film e1)"; fi
else fail sign_option "exit $?: $(head -n 1 err_sign)"; fi
if "$BMSSIM" simulate --protocol csv:dpos.csv --current-sign discharge-positive --points 6 --radial 6 --quiet \
     --out sign_sim 2>err_sim2 >/dev/null && grep -q '"complete": true' sign_sim/summary.json; then
  end=$(tail -n 1 sign_sim/truth.csv | cut -d, -f1)
  [ "${end%.*}" -ge 15000 ] && pass "sign_simulate_option (driven to t = $end s)" || fail sign_simulate_option "stopped at $end s"
else fail sign_simulate_option "exit $?: $(head -n 1 err_sim2)"; fi

# --- 3. --out never replaces a folder holding the user's files or an input of the run.
"$BMSSIM" simulate --cycles 1 --dt 1 --points 6 --radial 6 --quiet --out S 2>/dev/null >/dev/null
check_input_error out_holds_input "--out 'S'.*holds the input .*S/truth\.csv" S_unused -- \
  "$BMSSIM" estimate --data S/truth.csv --cell paper --quiet --out S
[ -s S/truth.csv ] && pass out_input_kept || fail out_input_kept "S/truth.csv is gone"
if "$BMSSIM" simulate --cycles 1 --dt 1 --points 6 --radial 6 --quiet --out S 2>/dev/null >/dev/null; then
  pass out_rerun_replaces_own_folder
else
  fail out_rerun_replaces_own_folder "a second run into a folder bmssim wrote exits $?"
fi
mkdir export && cp m60.csv export/raw.csv && echo '{"cycler": "own"}' > export/summary.json
check_input_error out_foreign_summary "--out 'export'.*files no bmssim run wrote" export_unused -- \
  "$BMSSIM" estimate --data m60.csv --cell paper --quiet --out export
cmp -s m60.csv export/raw.csv && pass out_foreign_kept || fail out_foreign_kept "export/raw.csv changed or gone"
echo extra > S/notes.txt
check_input_error out_added_file "--out 'S'.*files no bmssim run wrote" S_unused -- \
  "$BMSSIM" simulate --cycles 1 --dt 1 --quiet --out S
mkdir target && ln -s target link && ln -s nowhere dangling
check_input_error out_symlink "--out 'link'.*symbolic link" link_unused -- \
  "$BMSSIM" simulate --cycles 1 --dt 1 --quiet --out link
[ -L link ] && pass out_symlink_kept || fail out_symlink_kept "the link was replaced"
check_input_error out_dangling "--out 'dangling'.*symbolic link" dangling_unused -- \
  timeout 5 "$BMSSIM" simulate --cycles 1000 --quiet --out dangling

echo "$PASSED passed, $FAILED failed"
[ "$FAILED" -eq 0 ]
