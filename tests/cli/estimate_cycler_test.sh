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
arbin() {  # arbin FIRST LAST [DAY: the truth's t = 0 on 2010-10-DAY, 8 unless given] [FOLDER of truth.csv: sim]
  awk -F, -v first="$1" -v last="$2" -v day="${3:-8}" '
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
             0.09 + 0.001 * c }' "${4:-sim}/truth.csv"
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
  # A test stopped in cycle 2's CC charge and resumed at rest two days later (a power cycle, as six
  # files of CALCE CS2_35 do): the model rests over the pause and re-synchronises after it instead
  # of interpolating the charge current over two days (which would put it 40 Ah beyond full), and
  # the cut charge gives no counted capacity.
  mkdir cut
  if ! "$BMSSIM" simulate --cell paper --cycles 3 --dt 2 --points 6 --radial 6 --noise-v-mv 0.2 --quiet --out sim_rest \
       --protocol "Rest for 10 minutes; Discharge at 2.5 A for 2 hours or until 2.0 V; Charge at 2.5 A for 2 hours or until 3.6 V; Hold at 3.6 V for 1 hour or until 0.1 A" \
       2> err_sim_rest; then
    fail power_cycle "simulate: $(head -n 1 err_sim_rest)"
  fi
  arbin 1 2 8 sim_rest | awk -F, 'NR > 1 && $6 == 2 && $5 == 2 && ++n > 150 { exit } { print }' \
    > cut/cell_10_08_10_Channel_1-008.csv
  arbin 3 3 10 sim_rest > cut/cell_10_12_10_Channel_1-008.csv
  if [ ! -s cut/cell_10_12_10_Channel_1-008.csv ]; then
    :
  elif ! "$BMSSIM" estimate --data cut --no-learning --quiet --out est_cut 2> err_cut >/dev/null; then
    fail power_cycle "exit code $?: $(head -n 2 err_cut)"
  else
    python3 - est_cut <<'PY' && pass power_cycle || fail power_cycle "see above"
import csv, json, sys
d = sys.argv[1]
rows = list(csv.DictReader(open(d + "/estimates.csv")))
t = [float(r["t_s"]) for r in rows]
k = max(range(1, len(t)), key=lambda i: t[i] - t[i - 1])  # the first sample after the pause
after = [abs(float(r["z_v"])) for r in rows[k + 30:k + 90]]  # after the 25-sample re-synchronisation window
aging = list(csv.DictReader(open(d + "/aging.csv")))
cut = [a for a in aging if a["cycle"] == "2"]
print("pause %.0f s; |residual| over samples 30-90 after it: max %.2f mV; cycle 2 counted %s Ah, complete %s"
      % (t[k] - t[k - 1], 1e3 * max(after), cut[0]["counted_ah"] if cut else "-", cut[0]["counted_complete"] if cut else "-"))
ok = t[k] - t[k - 1] > 86400 and max(after) < 0.005 and cut and cut[0]["counted_complete"] == "0" and cut[0]["capacity_est_ah"] == ""
sys.exit(0 if ok else 1)
PY
  fi
  # Line 7 of the second file: its voltage (column 8) is no number.
  awk -F, -v OFS=, 'NR == 7 { $8 = "3.3V" } { print }' cell/cell_10_09_10_Channel_1-008.csv > bad.csv
  mv bad.csv cell/cell_10_09_10_Channel_1-008.csv
  check_input_error malformed "cell_10_09_10_Channel_1-008\.csv: line 7, column 8 \('Voltage\(V\)'\): not a finite number: '3\.3V'" \
    "$WORK/est_bad" -- "$BMSSIM" estimate --data cell --quiet --out est_bad
fi

echo "# $PASSED passed, $FAILED failed"
[ "$FAILED" -eq 0 ]
