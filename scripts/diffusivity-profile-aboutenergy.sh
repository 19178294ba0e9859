#!/usr/bin/env bash
# The cathode diffusivity profile on the About:Energy LFP 18650 records (docs/results/diagnosis.md,
# "A stoichiometry-dependent cathode diffusivity"): the truth DFN on each measured current
# (`simulate --protocol csv:RECORD`, mesh 20) over a grid of knee profiles
# (--effect diffusivity_profile_positive=S --effect diffusivity_profile_positive_knee=K), the
# whole-record RMSE against the measured voltage per record and point, then leave one record out:
# the point with the least pooled RMSE on the other two records, scored on the held-out one.
# Plots the measured voltage beside the plain DFN and two profiles. A measurement, not a test.
#
# Usage: scripts/diffusivity-profile-aboutenergy.sh [OUT_DIR]   (default out/diffusivity-profile)
# Environment: BMSSIM=path to use a given binary instead of `./bms sim`; SHARED=path of ../shared.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out=${1:-$root/out/diffusivity-profile}
shared=$(cd "${SHARED:-$root/../shared}" && pwd)
data=$shared/data/aboutenergy-lfp18650
if [ -n "${BMSSIM:-}" ]; then sim=("$BMSSIM"); else sim=("$root/bms" sim); fi
mkdir -p "$out"
points=("0 0.5")
for s in -1.5 -1 -0.75 -0.5 -0.25 0.5 1; do
  for k in 0 0.5 0.6 0.7 0.75 0.8 0.85 0.9; do points+=("$s $k"); done
done
for p in "${points[@]}"; do
  read -r s k <<< "$p"
  for r in 1C 2C Co20; do
    d=$out/run_${s}_${k}_$r
    [ -f "$d/truth.csv" ] ||
      "${sim[@]}" simulate --cell aboutenergy --protocol "csv:$data/LFP_25degC_$r.csv" \
        --effect "diffusivity_profile_positive=$s" --effect "diffusivity_profile_positive_knee=$k" \
        --quiet --out "$d" > /dev/null 2>&1 || echo "profile $s knee $k on $r: no run (solver failure)" >&2
  done
done
/usr/bin/python3 - "$out" "$data" <<'PY'
import csv, glob, math, os, re, sys
out, data = sys.argv[1:]
recs = ["1C", "2C", "Co20"]
meas = {r: list(csv.DictReader(open(f"{data}/LFP_25degC_{r}.csv"))) for r in recs}
volts = {r: [float(x["U[V]"]) for x in meas[r]] for r in recs}
def voltages(s, k, r):
    p = f"{out}/run_{s}_{k}_{r}/truth.csv"
    return [float(x["voltage_v"]) for x in csv.DictReader(open(p))] if os.path.exists(p) else []
pts = {}
for d in glob.glob(f"{out}/run_*_1C"):
    s, k = re.match(r".*/run_(.+)_(.+)_1C$", d).groups()
    ss = {}
    for r in recs:
        v = voltages(s, k, r)
        if not v: break
        # The model stops at its voltage limit: the rest is scored with its last value (as diagnose does).
        ss[r] = sum((1e3 * (v[min(i, len(v) - 1)] - m)) ** 2 for i, m in enumerate(volts[r]))
    if len(ss) == 3: pts[(s, k)] = ss
n = {r: len(volts[r]) for r in recs}
rms = lambda ss, rs: math.sqrt(sum(ss[r] for r in rs) / sum(n[r] for r in rs))
plain = pts[("0", "0.5")]
print(f"{len(pts)} grid points (of the profile's log10 factor at x = 1 and its knee)")
print("| held-out record | fitted on | profile fitted (log10 at x = 1, knee) | RMSE fitted records mV | held-out RMSE mV | plain DFN mV |")
print("|---|---|---|---|---|---|")
held_ss = {}
for h in recs:
    train = [r for r in recs if r != h]
    best = min(pts, key=lambda p: rms(pts[p], train))
    held_ss[h] = pts[best][h]
    print(f"| {h} | {' + '.join(train)} | {best[0]}, {best[1]} | {rms(pts[best], train):.1f} | {rms(pts[best], [h]):.1f} | {rms(plain, [h]):.1f} |")
print(f"pooled held-out {rms(held_ss, recs):.2f} mV, plain {rms(plain, recs):.2f} mV")
for r in recs:
    b = min(pts, key=lambda p: rms(pts[p], [r]))
    print(f"in-sample best on {r} alone: profile {b[0]}, knee {b[1]}: {rms(pts[b], [r]):.1f} mV (plain {rms(plain, [r]):.1f})")
for r in ("1C", "2C"):
    cols = [voltages(*p, r) for p in (("0", "0.5"), ("-0.5", "0.7"), ("-1.5", "0.9"))]
    with open(f"{out}/curves_{r}.dat", "w") as f:
        f.write("# t_s measured plain profile(-0.5,0.7) profile(-1.5,0.9)\n")
        for i, m in enumerate(meas[r]):
            vals = " ".join(f"{c[i]:.5f}" if i < len(c) else "nan" for c in cols)
            f.write(f"{m['Time [s]']} {m['U[V]']} {vals}\n")
PY
cat > "$out/plot.gp" <<GP
set terminal pngcairo size 1100,450 font ",10"
set output "$out/diffusivity_profile_aboutenergy.png"
set multiplot layout 1,2 title "About:Energy LFP 18650 (CC BY-SA 4.0, (c) About:Energy): measured vs truth DFN, plain and with a cathode diffusivity profile"
set xlabel "t (s)"; set ylabel "voltage (V)"; set yrange [2.4:3.3]; set key bottom left
do for [r in "1C 2C"] {
  set title r
  plot "$out/curves_".r.".dat" u 1:2 w l lw 2 lc rgb "black" t "measured", "" u 1:3 w l lc rgb "blue" t "plain DFN", \
       "" u 1:4 w l lc rgb "red" t "D x10^{-0.5} at x = 1, knee 0.7", "" u 1:5 w l lc rgb "orange" t "D x10^{-1.5} at x = 1, knee 0.9"
}
unset multiplot
GP
gnuplot "$out/plot.gp"
