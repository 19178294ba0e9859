#!/usr/bin/env bash
# The estimator in the operating envelope (docs/results/envelope.md): truths with a hidden film law
# x1.8, initial film +9 %, inventory -0.5 %, 0.2 mV noise, 5 CCCV cycles, at 5-45 C, self-heating,
# and with the sensors' errors; `bmssim estimate` (defaults, or the options given after OUT) on each.
#
#   scripts/envelope-study.sh BMSSIM OUT [estimate options...]
#
# Prints per truth: the film's median error per cycle, the worst of cycles 3-5, growth_err_pct,
# the worst inventory error, capacity_err_pct per cycle, film_within_2sd_pct per cycle, the share of
# learning ticks whose innovation test failed per cycle, and over the CC-charge ticks of cycles 3-5
# the median sd and median |error| (% of the true film). Truths are simulated once into OUT/truths.
set -euo pipefail
[ "$#" -ge 2 ] && [ -x "$1" ] || { echo "usage: $0 BMSSIM OUT [estimate options...]" >&2; exit 2; }
B=$(realpath "$1"); OUT=$2; shift 2
TAG=${TAG:-default}
H="--set film_growth_scale=1.8 --set r_film_initial_ohm_m2=0.00369619 --set inventory_scale=0.995"
S="--noise-i-ma 5 --effect current_offset=0.01 --noise-t-k 0.2 --effect temperature_offset=0.5"
T="--noise-t-k 0.2 --effect temperature_offset=0.5"
declare -A TRUTH=(
  [t05]="--set temperature_k=278.15" [t15]="--set temperature_k=288.15" [t25]="" [t35]="--set temperature_k=308.15"
  [t45]="--set temperature_k=318.15" [th]="--effect thermal=0.05"
  [o05]="--set temperature_k=278.15 $T" [o25]="$T"
  [s05]="--set temperature_k=278.15 $S" [s25]="$S" [s45]="--set temperature_k=318.15 $S" [sth]="--effect thermal=0.05 $S")
ORDER=${TRUTHS:-"t05 t15 t25 t35 t45 th o05 o25 s05 s25 s45 sth"}
for t in $ORDER; do
  if [ ! -f "$OUT/truths/$t/truth.csv" ]; then
    # shellcheck disable=SC2086
    "$B" simulate --cell paper --protocol cccv --cycles 5 --noise-v-mv 0.2 --seed 1 $H ${TRUTH[$t]} --quiet \
      --out "$OUT/truths/$t" > /dev/null
  fi
  "$B" estimate --data "$OUT/truths/$t/truth.csv" "$@" --out "$OUT/est/$TAG/$t" > /dev/null 2>&1
  python3 - "$OUT/est/$TAG/$t" "$t" <<'PY'
import csv, json, statistics as st, sys
d, name = sys.argv[1], sys.argv[2]
s = json.load(open(d + '/summary.json')); c = s['cycles']
fmt = lambda key, f: ' '.join(f % x[key] if x.get(key) is not None else '-' for x in c)
worst = max(x['r_film_err_median_pct'] for x in c if x['cycle'] >= 3)
inv = max(abs(x['inventory_err_end_pct'] or 0) for x in c)
sd, err = [], []
for r in csv.DictReader(open(d + '/estimates.csv')):
    if r['mode'] != 'cc_charge' or int(r['cycle']) < 3 or not r['r_film_true_ohm_m2'] or not r.get('r_film_sd_ohm_m2'): continue
    t = float(r['r_film_true_ohm_m2']); sd.append(float(r['r_film_sd_ohm_m2']) / t * 100)
    err.append(abs(float(r['r_film_est_ohm_m2']) - t) / t * 100)
sharp = f"sd {st.median(sd):.2f} / err {st.median(err):.2f}" if sd else "-"
print(f"{name:4s} film% {fmt('r_film_err_median_pct', '%.2f')} | worst3-5 {worst:.2f} | growth {s['growth_err_pct']:.1f} | "
      f"inv {inv:.3f} | cap% {fmt('capacity_err_pct', '%.3f')} | in2sd% {fmt('film_within_2sd_pct', '%.0f')} | "
      f"misfit% {fmt('misfit_pct', '%.0f')} | c3-5 median {sharp}")
PY
done
