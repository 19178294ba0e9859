#!/usr/bin/env bash
# Integration test: `bmssim estimate` on a cycler's exports. Two CCCV cycles of the paper cell,
# written as two Arbin files (Date_Time, Cycle_Index and Step_Index restarting in each, current
# charge-positive, 2 s samples with a logging gap under current, the cycler's capacity and
# internal-resistance columns), read from a folder and as two --data files given in reverse
# order: the same estimate, charges in summary.json with the contract's keys, the comparison
# with the cycler (aging.csv). A malformed file in the folder exits 2 naming its line and column.
#
# Usage: estimate_cycler_test.sh BMSSIM
set -u
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
[ "$#" -eq 1 ] && [ -x "$1" ] || { echo "usage: $0 BMSSIM" >&2; exit 2; }
BMSSIM=$(realpath "$1")
WORK=$(mktemp -d "${TMPDIR:-/tmp}/bmssim_estimate_cycler.XXXXXX") || exit 1
trap 'rm -rf "$WORK"' EXIT
cd "$WORK" || exit 1
# shellcheck source=input_error_check.sh
. "$HERE/input_error_check.sh"

# truth.csv -> an Arbin export of cycles FIRST..LAST (Date_Time: 2010-10-08 14:00:00 at the truth's
# t = 0; Test_Time from 0 at the file's first sample); a 120 s logging gap in each file's first charge.
arbin() {  # arbin FIRST LAST
  awk -F, -v first="$1" -v last="$2" -v day=8 '
    NR == 1 { for (k = 1; k <= NF; k++) col[$k] = k
              print "Data_Point,Test_Time(s),Date_Time,Step_Time(s),Step_Index,Cycle_Index,Current(A),Voltage(V)," \
                    "Charge_Capacity(Ah),Discharge_Capacity(Ah),Internal_Resistance(Ohm)"; next }
    { c = $col["cycle"]; if (c < first || c > last) next
      t = $col["t_s"]; if (t0 == "") t0 = t; tt = t - t0
      i = $col["current_meas_a"]; m = $col["mode"]
      if (m == "cc_charge" && !gapped) { nchg++; if (nchg > 20 && nchg <= 80) next; if (nchg > 80) gapped = 1 }
      if (i < 0) qc += -i * 2 / 3600; else qd += i * 2 / 3600
      step = m == "rest" ? 1 : m == "cc_charge" ? 2 : m == "cv_charge" ? 3 : 4
      s = int(t) + 50400
      printf "%d,%.3f,2010-10-%02d %02d:%02d:%02d,0,%d,%d,%.6f,%.6f,%.6f,%.6f,%.5f\n", ++n, tt, day + int(s / 86400), \
             int(s / 3600) % 24, int(s / 60) % 60, s % 60, step, c - first + 1, -i, $col["voltage_meas_v"], qc, qd, \
             0.09 + 0.001 * c }' sim/truth.csv
}

if ! "$BMSSIM" simulate --cell paper --protocol cccv --cycles 3 --dt 2 --points 6 --radial 6 --noise-v-mv 0.2 \
     --quiet --out sim 2> err_sim; then
  fail simulate "$(head -n 1 err_sim)"
else
  mkdir cell
  arbin 1 2 > cell/cell_10_08_10_Channel_1-008.csv
  arbin 3 3 > cell/cell_10_09_10_Channel_1-008.csv
  printf 'Unnamed: 0,TEST REPORT\n,x\n' > cell/cell_10_08_10_Info.csv  # skipped as no time series
  if ! "$BMSSIM" estimate --data cell --quiet --out est 2> err_est >/dev/null; then
    fail folder "exit code $?: $(head -n 2 err_est)"
  elif ! grep -q '"Arbin layout, 2 file(s)' est/summary.json; then
    fail folder "summary.json does not say how the files were read: $(grep data_layout est/summary.json)"
  elif ! grep -q '2 logging gap(s) (2 under current, longest 122 s)' est/summary.json; then
    fail folder "the logging gap under current is not reported: $(grep data_layout est/summary.json)"
  else
    pass folder
  fi
  n_charges=$(grep -c '"r_growth_ohm"' est/summary.json 2>/dev/null)
  keys_ok=1
  for k in index t_start_s t_end_s capacity_ah capacity_sd_ah r_film_ohm_m2 r_film_sd_ohm_m2 r_growth_ohm; do
    grep -q "\"$k\"" est/summary.json 2>/dev/null || keys_ok=0
  done
  if [ "${n_charges:-0}" -lt 2 ] || [ "$keys_ok" -ne 1 ]; then
    fail charges "$n_charges charges, contract keys present: $keys_ok"
  else
    pass charges
  fi
  if [ ! -s est/aging.csv ] || [ "$(wc -l < est/aging.csv)" -lt 3 ]; then
    fail aging "aging.csv: $(cat est/aging.csv 2>/dev/null | head -n 3)"
  else
    pass aging
  fi
  if ! "$BMSSIM" estimate --data cell/cell_10_09_10_Channel_1-008.csv --data cell/cell_10_08_10_Channel_1-008.csv \
       --quiet --out est2 2> err_est2 >/dev/null; then
    fail files_in_reverse "exit code $?: $(head -n 2 err_est2)"
  elif ! cmp -s est/estimates.csv est2/estimates.csv; then
    fail files_in_reverse "estimates.csv differs from the folder's"
  else
    pass files_in_reverse
  fi
  # Line 7 of the second file: its voltage (column 8) is no number.
  awk -F, -v OFS=, 'NR == 7 { $8 = "3.3V" } { print }' cell/cell_10_09_10_Channel_1-008.csv > bad.csv
  mv bad.csv cell/cell_10_09_10_Channel_1-008.csv
  check_input_error malformed "cell_10_09_10_Channel_1-008\.csv: line 7, column 8 \('Voltage\(V\)'\): not a finite number: '3\.3V'" \
    "$WORK/est_bad" -- "$BMSSIM" estimate --data cell --quiet --out est_bad
fi

echo "# $PASSED passed, $FAILED failed"
[ "$FAILED" -eq 0 ]
