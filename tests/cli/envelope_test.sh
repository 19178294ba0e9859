#!/usr/bin/env bash
# Integration test: the operating envelope's columns (contract: simulate's temperature_meas_k and
# capacity_ah).
#
# Usage: envelope_test.sh BMSSIM
#
# simulate: temperature_meas_k is the truth's temperature plus --effect temperature_offset and
# --noise-t-k (mean and spread as asked); temperature noise leaves the voltage and current draws
# of the same seed unchanged; capacity_ah is the open-circuit capacity of the truth's inventory
# (a 0.5 % smaller inventory gives a capacity 0.4-0.6 % smaller); bad values exit 2.
set -u
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
[ "$#" -ge 1 ] && [ -x "$1" ] || { echo "usage: $0 BMSSIM" >&2; exit 2; }
BMSSIM=$(realpath "$1")
WORK=$(mktemp -d "${TMPDIR:-/tmp}/bmssim_envelope.XXXXXX") || exit 1
trap 'rm -rf "$WORK"' EXIT
cd "$WORK" || exit 1
# shellcheck source=input_error_check.sh
. "$HERE/input_error_check.sh"

check_input_error noise_t_negative "--noise-t-k" bad1 -- "$BMSSIM" simulate --noise-t-k -1 --out bad1
check_input_error temperature_offset_range "temperature_offset" bad2 -- \
  "$BMSSIM" simulate --effect temperature_offset=80 --out bad2

sim() { "$BMSSIM" simulate --protocol "Discharge at 1C for 10 minutes; Rest for 5 minutes" --quiet "$@"; }
sim --noise-v-mv 0.2 --noise-i-ma 5 --out plain > /dev/null || fail sim_plain "exit $?"
sim --noise-v-mv 0.2 --noise-i-ma 5 --noise-t-k 0.3 --effect temperature_offset=0.5 --out temp > /dev/null ||
  fail sim_temp "exit $?"
sim --set inventory_scale=0.995 --out inv > /dev/null || fail sim_inv "exit $?"

python3 - plain/truth.csv temp/truth.csv inv/truth.csv <<'PY' && pass sensor_and_capacity || fail sensor_and_capacity "see above"
import csv, statistics as st, sys
plain, temp, inv = (list(csv.DictReader(open(f))) for f in sys.argv[1:4])
ok = True
def check(cond, what):
    global ok
    if not cond:
        print("   ", what); ok = False
d = [float(r['temperature_meas_k']) - float(r['temperature_k']) for r in temp]
check(abs(st.mean(d) - 0.5) < 0.02 and abs(st.pstdev(d) - 0.3) < 0.02, f"offset/noise {st.mean(d)} {st.pstdev(d)}")
check(all(float(r['temperature_meas_k']) == float(r['temperature_k']) for r in plain), "no sensor error: meas != truth")
check(all(a['voltage_meas_v'] == b['voltage_meas_v'] and a['current_meas_a'] == b['current_meas_a']
          for a, b in zip(plain, temp)), "temperature noise changed the voltage or current draws")
c0, c1 = float(plain[0]['capacity_ah']), float(inv[0]['capacity_ah'])
check(2.4 < c0 < 2.7, f"nominal capacity {c0}")
check(-0.6 < (c1 / c0 - 1) * 100 < -0.4, f"capacity at inventory -0.5 %: {(c1 / c0 - 1) * 100} %")
sys.exit(0 if ok else 1)
PY

echo "passed $PASSED, failed $FAILED"
[ "$FAILED" -eq 0 ]
