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
# negative, PyBaMM's header) at 1, 2, 30 and 60 s.
"$BMSSIM" simulate --cell paper --protocol cccv --cycles 2 --dt 1 --points 6 --radial 6 --noise-v-mv 0.2 \
  --quiet --out sim 2> err_sim >/dev/null || { echo "simulate failed: $(head -n 1 err_sim)"; exit 1; }
for s in 1 2 30 60; do
  awk -F, -v s="$s" 'NR == 1 { for (k = 1; k <= NF; k++) col[$k] = k; print "Time [s],Current [A],Voltage [V]"; next }
    ($col["t_s"] % s) == 0 { printf "%s,%.6f,%.6f\n", $col["t_s"], -$col["current_meas_a"], $col["voltage_meas_v"] }' \
    sim/truth.csv > "m$s.csv"
done
final_film() { tail -n 1 "$1/estimates.csv" | awk -F, '{ print $5 }'; }

# --- 1. Sampling: a model step per sample with the firmware's catch-up of the ticks between
# samples (a 2 s record: one row per sample, the film physical and close to the 1 s record's);
# coarser records are refused naming the interval the estimator needs (2 s).
if "$BMSSIM" estimate --data m1.csv --cell paper --quiet --out e1 2> err_e1 >/dev/null; then
  ref=$(final_film e1)
  s=2
  if "$BMSSIM" estimate --data "m$s.csv" --cell paper --quiet --out "e$s" 2> "err_e$s" >/dev/null; then
    film=$(final_film "e$s")
    rows=$(($(wc -l < "e$s/estimates.csv") - 1))
    dev=$(awk -v a="$film" -v b="$ref" 'BEGIN { printf "%.2f", (a - b) / b * 100 }')
    if awk -v a="$film" -v b="$ref" 'BEGIN { exit !(a > 0 && (a - b) / b < 0.05 && (b - a) / b < 0.05) }' &&
       [ "$rows" -eq $(($(wc -l < "m$s.csv") - 1)) ]; then
      pass "sampled_${s}s (final film $film vs $ref at 1 s: $dev %, $rows rows)"
    else
      fail "sampled_${s}s" "final film $film vs $ref at 1 s ($dev %), $rows rows"
    fi
  else
    fail "sampled_${s}s" "exit code $?: $(head -n 1 "err_e$s")"
  fi
else
  fail sampled_1s "exit code $?: $(head -n 1 err_e1)"
fi
for s in 30 60; do
  check_input_error "sampled_${s}s" "m$s\\.csv: sampled every $s s .*needs a sample at least every 2 s" "e$s" -- \
    "$BMSSIM" estimate --data "m$s.csv" --cell paper --quiet --out "e$s"
done

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

# --- 5. Units: a current in mA under an [A] header is refused by diagnose as by simulate.
awk -F, 'NR == 1 { print; next } { printf "%s,%.3f,%s\n", $1, $2 * 1000, $3 }' m30.csv > milli.csv
check_input_error milliamps_diagnose 'milli\.csv: sample 1 .*current -?2500 A is beyond .*mA labelled \[A\]' milli_d -- \
  "$BMSSIM" diagnose --data milli.csv --cell paper --out milli_d
check_input_error milliamps_simulate 'milli\.csv: sample 1 .*current -?2500 A is beyond .*mA labelled \[A\]' milli_s -- \
  "$BMSSIM" simulate --protocol csv:milli.csv --quiet --out milli_s

# --- 6. Memory bounded by the samples, not by a grid: 1 ms samples around a three-day rest
# need no more memory than the same samples without the rest (relative, so that a sanitizer's
# shadow memory does not decide it; a 1 ms grid over the rest would be 259 million steps).
python3 - <<'PY'
for name, gap in (('ms.csv', 259200), ('ms_nogap.csv', 0)):
    with open(name, 'w') as f:
        f.write('Time [s],Current [A],Voltage [V]\n')
        for k in range(20000):
            f.write('%.3f,0,3.3\n' % (k * 0.001 + (gap if k >= 10000 else 0)))
PY
rss_of() { # RSS in kB of bmssim CMD on FILE, output folder OUT
  local cmd=$1 file=$2 out=$3 args
  if [ "$cmd" = estimate ]; then args=(estimate --data "$file" --cell paper); else args=(simulate --protocol "csv:$file"); fi
  /usr/bin/time -o "rss_$out" -f %M "$BMSSIM" "${args[@]}" --quiet --out "$out" >/dev/null 2>&1
  tail -n 1 "rss_$out"
}
for cmd in estimate simulate; do
  kb=$(rss_of "$cmd" ms.csv "ms_$cmd"); base=$(rss_of "$cmd" ms_nogap.csv "ms_nogap_$cmd")
  if [ -f "ms_$cmd/summary.json" ] && [ $(( ${kb:-999999} - ${base:-0} )) -lt 16384 ]; then
    pass "memory_${cmd}_gap ($kb kB with the rest, $base kB without)"
  else fail "memory_${cmd}_gap" "$kb kB with the rest, $base kB without, summary $(ls "ms_$cmd" 2>&1 | head -c 100)"; fi
done
# A record entirely at rest: nothing to diagnose, said before any work.
check_input_error rest_diagnose 'ms\.csv: no current flows in the record' ms_d -- \
  "$BMSSIM" diagnose --data ms.csv --cell paper --out ms_d

# --- 7. Checks that need no work run before the work.
check_input_error rest_forever "--protocol step 'Rest for 1e12 hours'.*longer than a step may run" rest12 -- \
  timeout 20 "$BMSSIM" simulate --protocol "Rest for 1e12 hours" --quiet --out rest12
[ ! -e rest12 ] && pass rest_forever_no_folder || fail rest_forever_no_folder "rest12 exists: $(ls rest12)"
start=$(date +%s)
check_input_error hil_fault_first "--fault: 'crc=0.6,drop=0.6': the rates add up to more than 1" hf -- \
  timeout 60 "$BMSSIM" hil --bus uml --fault crc=0.6,drop=0.6 --cycles 1 --out hf
[ $(($(date +%s) - start)) -lt 5 ] && pass hil_fault_before_boot || fail hil_fault_before_boot "took $(($(date +%s) - start)) s"

# --- 8. Messages that say what to do.
sed 's/,/;/g; s/\./,/g' m60.csv > eu.csv
check_input_error european_csv "eu\.csv: line 1: columns separated by ';'.*'\.' as the decimal point" eu_o -- \
  "$BMSSIM" estimate --data eu.csv --cell paper --quiet --out eu_o
iconv -f UTF-8 -t UTF-16 m60.csv > u16.csv
check_input_error utf16 'u16\.csv: NUL bytes in the text \(UTF-16' u16_o -- \
  "$BMSSIM" estimate --data u16.csv --cell paper --quiet --out u16_o
"$BMSSIM" simulate --cycles 1e3 --quiet --out c1e3 2> err_c1e3 >/dev/null
rc=$?
if [ $rc -eq 2 ] && grep -q "^bmssim: --cycles: '1e3' is not a whole number.*1000, not 1e3" err_c1e3 && [ ! -e c1e3 ]; then
  pass cycles_1e3
else fail cycles_1e3 "exit $rc: $(head -n 1 err_c1e3)"; fi
FIRMWARE=$(dirname "$BMSSIM")/../apps/bms-firmware
if [ -x "$FIRMWARE" ]; then
  check_input_error firmware_long_can "--can must name a CAN interface of 1\.\.15 characters" fw_o -- \
    "$FIRMWARE" --can averyveryverylongcanname --lockstep
fi

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
  "$BMSSIM" estimate --data m2.csv --cell paper --quiet --out export
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
