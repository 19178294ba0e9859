# shellcheck shell=bash
# Sourced by the diagnose --write-cell integration tests (not a test itself): simulates each
# truth record's current with the plain About:Energy cell and with the written cell file, and
# counts a failure (through the caller's `fail`) unless the written cell is within a fifth of
# the plain cell's RMSE against the measured voltage.
#
# Usage (in the test's work folder, after `fail` is defined):
#   discharge_truths BMSSIM SEED [--effect NAME=VALUE ...]   # truth1/, truth2/, truth4/
#   written_cell_within_a_fifth BMSSIM A [A ...]             # needs truthA/ and cell/
rmse_mv() { # SIM TRUTH: RMS (mV) of voltage_v of SIM minus voltage_meas_v of TRUTH (SIM's last row past its end)
  python3 -c '
import csv, math, sys
v = [float(r["voltage_v"]) for r in csv.DictReader(open(sys.argv[1]))]
m = [float(r["voltage_meas_v"]) for r in csv.DictReader(open(sys.argv[2]))]
print("%.3f" % math.sqrt(sum((1e3 * (v[min(k, len(v) - 1)] - x)) ** 2 for k, x in enumerate(m)) / len(m)))' "$1" "$2"
}
written_cell_within_a_fifth() {
  local bmssim=$1 i c plain aug
  shift
  for i in "$@"; do
    for c in aboutenergy cell/cell.bpx.json; do
      "$bmssim" simulate --cell "$c" --protocol "csv:truth$i/truth.csv" --quiet --out "sim_$(basename "$c")_$i" > /dev/null 2>&1 ||
        fail "simulate $c on $i A" "refused"
    done
    plain=$(rmse_mv "sim_aboutenergy_$i/truth.csv" "truth$i/truth.csv")
    aug=$(rmse_mv "sim_cell.bpx.json_$i/truth.csv" "truth$i/truth.csv")
    echo "# $i A: plain cell $plain mV, augmented cell $aug mV"
    awk -v a="$aug" -v p="$plain" 'BEGIN { exit !(a <= 0.2 * p && p > 5) }' || fail "$i A" "augmented $aug mV, plain $plain mV"
  done
}

# Full discharges at 1, 2 and 4 A of the About:Energy truth with the given effects, 0.1 mV voltage
# noise, on a 12-volume mesh at rtol 1e-7 (not the diagnosis's meshes); exits 1 on a refusal.
discharge_truths() {
  local bmssim=$1 seed=$2 i
  shift 2
  for i in 1 2 4; do
    "$bmssim" simulate --cell aboutenergy --protocol "Rest for 1 minute; Discharge at $i A for 8000 seconds or until 2.5 V; Rest for 10 minutes" \
      --dt 2 --points 12 --radial 12 --rtol 1e-7 --noise-v-mv 0.1 --seed "$seed" "$@" --quiet --out "truth$i" > /dev/null 2> "err_truth$i" ||
      { echo "not ok - truth $i A: $(head -n 1 "err_truth$i")"; exit 1; }
  done
}
