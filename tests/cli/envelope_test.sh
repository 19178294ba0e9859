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
# estimate: on a 5 C truth with a hidden film law x1.8, film +9 %, inventory -0.5 % (3 cycles,
# 0.2 mV), the film of cycle 3 within 2 % and inside 2 sd on >= 90 % of its CC-charge ticks, the
# capacity within 0.1 %, with the new columns; the same file without temperature_meas_k (the
# model isothermal at 25 C) is at least 10 % off: the estimator reads the sensor's temperature.
# The current sensor's offset removed (below).
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

# A truth whose anode is full below the upper voltage limit at rest (1 % more lithium): its
# capacity ends at the full anode (open_circuit_capacity.hpp), finite on every row, and estimate
# reads its own simulate's file.
sim --set inventory_scale=1.01 --out full > /dev/null || fail sim_capacity_full_anode "exit $?"
if ! grep -qi ',nan$' full/truth.csv && "$BMSSIM" estimate --data full/truth.csv --out est_full > /dev/null 2>&1; then
  pass estimate_takes_full_anode_capacity
else
  fail estimate_takes_full_anode_capacity "capacity_ah not finite, or estimate refused the file"
fi

H="--set film_growth_scale=1.8 --set r_film_initial_ohm_m2=0.00369619 --set inventory_scale=0.995"
# shellcheck disable=SC2086
"$BMSSIM" simulate --cycles 3 --noise-v-mv 0.2 --seed 3 --set temperature_k=278.15 $H --quiet --out cold > /dev/null ||
  fail sim_cold "exit $?"
python3 - cold/truth.csv cold_noT.csv <<'PY'
import csv, sys
r = csv.reader(open(sys.argv[1])); w = csv.writer(open(sys.argv[2], 'w', newline=''))
h = next(r); k = h.index('temperature_meas_k'); w.writerow(h[:k] + h[k + 1:])
for row in r: w.writerow(row[:k] + row[k + 1:])
PY
"$BMSSIM" estimate --data cold/truth.csv --out est > /dev/null 2>&1 || fail estimate_cold "exit $?"
"$BMSSIM" estimate --data cold_noT.csv --out est_noT > /dev/null 2>&1 || fail estimate_cold_isothermal "exit $?"
python3 - est/summary.json est_noT/summary.json est/estimates.csv <<'PY' && pass estimate_follows_temperature ||
import csv, json, sys
s, n = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
c3 = [c for c in s['cycles'] if c['cycle'] == 3][0]
n3 = [c for c in n['cycles'] if c['cycle'] == 3][0]
print("    cycle 3: film %.2f %%, in 2 sd %.0f %%, capacity %.4f %%; isothermal film %.1f %%" % (
    c3['r_film_err_median_pct'], c3['film_within_2sd_pct'], c3['capacity_err_pct'], n3['r_film_err_median_pct']))
head = next(csv.reader(open(sys.argv[3])))
need = ['r_film_sd_ohm_m2', 'capacity_est_ah', 'capacity_sd_ah', 'capacity_true_ah', 'innovation_test_ratio']
ok = (c3['r_film_err_median_pct'] <= 2.0 and c3['film_within_2sd_pct'] >= 90.0 and abs(c3['capacity_err_pct']) <= 0.1
      and n3['r_film_err_median_pct'] >= 10.0 and all(k in head for k in need))
sys.exit(0 if ok else 1)
PY
  fail estimate_follows_temperature "see the numbers above"
# The contract's charges carry the estimator's capacity and sds (not the counted charge), each
# charge's capacity within 0.5 % of the truth's at the charge's end, its sd finite and positive.
python3 - est/summary.json cold/truth.csv <<'PY' && pass charges_capacity_estimated || fail charges_capacity_estimated "see above"
import bisect, csv, json, sys
s = json.load(open(sys.argv[1]))
t, cap = [], []
for row in csv.DictReader(open(sys.argv[2])):
    t.append(float(row['t_s'])); cap.append(float(row['capacity_ah']))
ok = len(s['charges']) >= 2
for c in s['charges']:
    truth = cap[min(bisect.bisect_left(t, c['t_end_s']), len(t) - 1)]
    err = (c['capacity_ah'] - truth) / truth * 100
    print("    charge %d: %s capacity %.4f Ah (sd %.4f), truth %.4f: %.3f %%; film sd %s; counted %.4f Ah" % (
        c['index'], c['capacity_source'], c['capacity_ah'], c['capacity_sd_ah'], truth, err, c['r_film_sd_ohm_m2'],
        c['counted_ah']))
    ok = ok and c['capacity_source'] == 'estimator' and abs(err) <= 0.5 and c['capacity_sd_ah'] > 0
    ok = ok and (c['r_film_sd_ohm_m2'] or 0) > 0
sys.exit(0 if ok else 1)
PY

# A stated parameter spread (set 4's tolerances as 1-sigma): the fit is the same (the identified
# initial film and gain byte for byte), the sd and film equal where the prior is held (no fit
# yet); on every other learning tick of a CC charge the fit's sd carries the spread, so the level
# reported is the inverse-variance mean of the prior (the nominal film grown by the nominal law:
# initial film of the first row + G, G = (fit - initial) / gain) and the fit: strictly between the
# two, with an sd wider than the fit's alone without the spread.
"$BMSSIM" estimate --data cold/truth.csv --spread-anode-i0 0.1732 --spread-cathode-i0 0.1732 --spread-transport 0.1155 \
  --spread-area 0.01732 --out est_spread > /dev/null 2>&1 || fail estimate_spread "exit $?"
python3 - est/estimates.csv est_spread/estimates.csv <<'PY' && pass stated_spread_fuses_the_prior_and_the_fit ||
import csv, sys
a, b = (list(csv.DictReader(open(f))) for f in sys.argv[1:3])
same_fit = len(a) == len(b) and all(x['film_initial_est_ohm_m2'] == y['film_initial_est_ohm_m2'] and
                                    x['growth_gain_est'] == y['growth_gain_est'] for x, y in zip(a, b))
r_nom = float(a[0]['film_initial_est_ohm_m2'])
held, fused, bad = 0, 0, 0
for x, y in zip(a, b):
    if x['rcsi_active'] != '1' or x['mode'] != 'cc_charge':
        continue
    fit, f = float(x['r_film_est_ohm_m2']), float(y['r_film_est_ohm_m2'])
    sd_fit, sd = float(x['r_film_sd_ohm_m2']), float(y['r_film_sd_ohm_m2'])
    if sd == sd_fit and f == fit:
        held += 1
        continue
    fused += 1
    prior = r_nom + (fit - float(x['film_initial_est_ohm_m2'])) / float(x['growth_gain_est'])
    lo, hi = min(prior, fit), max(prior, fit)
    bad += not (lo < f < hi and sd > sd_fit)
print("    learning ticks: %d held prior (equal), %d fused, %d not between the prior and the fit or not wider" % (
    held, fused, bad))
sys.exit(0 if same_fit and held and fused and not bad else 1)
PY
  fail stated_spread_fuses_the_prior_and_the_fit "see the numbers above"

# The current sensor's offset: a 10 mA offset with 5 mA noise on a 3-cycle truth (25 C, the
# hidden film law). It is measured between two CV end points of the same kind (within 5 % of
# 10 mA); with it removed the capacity of cycle 3 is within 0.1 % and the film within 2 %, and
# without (--no-current-offset) the capacity is at least 0.3 % off. Both with --no-area-scale: the
# capacity from the identified inventory is what the offset biases (with the electrode-capacity
# scale on, the capacity comes from counted charge between CV ends, where a charge and a
# discharge span take the offset with opposite signs: measured 0.113 % with the removal and 0.072 %
# without on this truth; docs/results/envelope.md "Capacity").
# shellcheck disable=SC2086
"$BMSSIM" simulate --cycles 3 --noise-v-mv 0.2 --noise-i-ma 5 --effect current_offset=0.01 --seed 4 $H --quiet \
  --out offset > /dev/null || fail sim_offset "exit $?"
"$BMSSIM" estimate --data offset/truth.csv --no-area-scale --out est_off > /dev/null 2>&1 ||
  fail estimate_offset "exit $?"
"$BMSSIM" estimate --data offset/truth.csv --no-area-scale --no-current-offset --out est_nooff > /dev/null 2>&1 ||
  fail estimate_no_offset "exit $?"
python3 - est_off/summary.json est_nooff/summary.json est_off/estimates.csv <<'PY' && pass current_offset_removed ||
import csv, json, sys
s, n = json.load(open(sys.argv[1])), json.load(open(sys.argv[2]))
c3 = [c for c in s['cycles'] if c['cycle'] == 3][0]
n3 = [c for c in n['cycles'] if c['cycle'] == 3][0]
head = next(csv.reader(open(sys.argv[3])))
print("    offset %.3f mA (ablation %.3f); cycle 3: film %.2f %%, capacity %.3f %%; without: film %.2f %%, capacity %.3f %%"
      % (s['current_offset_a'] * 1e3, n['current_offset_a'] * 1e3, c3['r_film_err_median_pct'],
         c3['capacity_err_pct'], n3['r_film_err_median_pct'], n3['capacity_err_pct']))
ok = (abs(s['current_offset_a'] - 0.01) <= 0.0005 and n['current_offset_a'] == 0 and
      abs(c3['capacity_err_pct']) <= 0.1 and c3['r_film_err_median_pct'] <= 2.0 and
      abs(n3['capacity_err_pct']) >= 0.3 and 'current_offset_est_a' in head)
sys.exit(0 if ok else 1)
PY
  fail current_offset_removed "see the numbers above"

# A current gain (+0.5 %) beside a 5 mA offset (3 cycles, the hidden film law): the film path
# learned cycle 1's charge on the offset current; when the offset is removed it restarts from its
# prior, so the model is not left at cycle 1's inventory and cycle 3's charge keeps cycle 2's fit
# (film of cycle 3 within 4 %; 7.9 % when the path kept what it learned on the old current).
# shellcheck disable=SC2086
"$BMSSIM" simulate --cycles 3 --noise-v-mv 0.2 --noise-i-ma 5 --effect current_gain=0.005 --effect current_offset=0.005 \
  --seed 1 $H --quiet --out gain > /dev/null || fail sim_gain_offset "exit $?"
"$BMSSIM" estimate --data gain/truth.csv --out est_gain > /dev/null 2>&1 || fail estimate_gain_offset "exit $?"
python3 - est_gain/summary.json <<'PY' && pass offset_change_restarts_the_fit ||
import json, sys
s = json.load(open(sys.argv[1]))
film = [c['r_film_err_median_pct'] for c in s['cycles']]
print("    offset %.3f mA; film %% by cycle: %s" % (s['current_offset_a'] * 1e3, ' '.join('%.2f' % f for f in film)))
sys.exit(0 if abs(s['current_offset_a'] - 0.005) <= 0.00025 and len(film) == 3 and film[2] <= 4.0 else 1)
PY
  fail offset_change_restarts_the_fit "see the numbers above"

# A current gain alone (-0.5 %, 2 cycles, the hidden film law): cycle 1's fit ends about 1 % of
# inventory from the prior's, so the re-synchronisation after it restarts the fit. A restarted fit
# reads the gain's within-charge ramp as inventory for most of its first charge (the film 9 % off at
# the defaults). With --hold-restarted-charge the path reports the fit it had until the restarted
# one has learned a whole charge: the film of cycle 2 within 4 %. Off by default: where the
# inventory settles over several charges it costs more than it gives (docs/results/envelope.md).
# shellcheck disable=SC2086
"$BMSSIM" simulate --cycles 2 --noise-v-mv 0.2 --noise-i-ma 5 --effect current_gain=-0.005 \
  --seed 1 $H --quiet --out gainonly > /dev/null || fail sim_gain "exit $?"
"$BMSSIM" estimate --data gainonly/truth.csv --out est_gainonly > /dev/null 2>&1 || fail estimate_gain "exit $?"
"$BMSSIM" estimate --data gainonly/truth.csv --hold-restarted-charge --out est_gainhold > /dev/null 2>&1 ||
  fail estimate_gain_hold "exit $?"
python3 - est_gainonly/summary.json est_gainhold/summary.json <<'PY' && pass restarted_charge_is_held ||
import json, sys
film = [[c['r_film_err_median_pct'] for c in json.load(open(f))['cycles']] for f in sys.argv[1:]]
print("    film %% by cycle: defaults %s, held %s" % tuple(' '.join('%.2f' % f for f in x) for x in film))
sys.exit(0 if all(len(x) == 2 for x in film) and abs(film[1][1]) <= 4.0 and abs(film[0][1]) > 4.0 else 1)
PY
  fail restarted_charge_is_held "see the numbers above"

# A current gain enters the capacity once (blind set 5's seed-10 truth: gain +0.394 %, offset
# 2.8 mA, voltage offset 0.04 mV, the temperature sensor 0.5 K off; 5 cycles). The electrode-capacity
# scale counts the charge between CV ends in the sensor's amperes, so the capacity carries the gain
# once: the worst capacity error of cycles 3-5 within 1.25 x the gain (0.49 %). Each span is
# measured at one model inventory (the CV end before its re-synchronisation); pinned after it, a
# span read its anode's move at one inventory and the capacity at the fit's (which takes the gain
# up too): +0.81 % in cycle 3, twice the gain (docs/results/envelope.md, "A current gain enters
# the capacity once").
"$BMSSIM" simulate --cell paper --protocol cccv --cycles 5 --noise-v-mv 0.2 --noise-i-ma 5 --noise-t-k 0.2 --seed 10 \
  --set r_film_initial_ohm_m2=0.002847832945374552 --set film_growth_scale=2.4391386376673876 \
  --set side_i0_scale=1.079742043473983 --set inventory_scale=1.0077109224036767 \
  --effect current_offset=0.0027509638604233406 --effect current_gain=0.003942408245636191 \
  --effect voltage_offset=4.427628850627529e-05 --effect temperature_offset=-0.5 --quiet \
  --out gaincap > /dev/null || fail sim_gain_capacity "exit $?"
"$BMSSIM" estimate --data gaincap/truth.csv --out est_gaincap > /dev/null 2>&1 || fail estimate_gain_capacity "exit $?"
python3 - est_gaincap/summary.json <<'PY' && pass gain_enters_the_capacity_once ||
import json, sys
s = json.load(open(sys.argv[1]))
cap = [c['capacity_err_pct'] for c in s['cycles']]
worst = max(abs(c) for c in cap[2:])
print("    area scale %.5f; capacity err %% by cycle: %s; worst of cycles 3-5 %.3f %% (gain 0.394 %%)" % (
    s['area_scale'], ' '.join('%.3f' % c for c in cap), worst))
sys.exit(0 if len(cap) == 5 and s['area_scale'] != 1.0 and worst <= 1.25 * 0.394 else 1)
PY
  fail gain_enters_the_capacity_once "see the numbers above"

echo "passed $PASSED, failed $FAILED"
[ "$FAILED" -eq 0 ]
