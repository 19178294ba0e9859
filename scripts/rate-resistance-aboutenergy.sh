#!/usr/bin/env bash
# The About:Energy LFP 18650 records seen as an apparent resistance (docs/results/diagnosis.md,
# "The overpotential as a resistance of the discharged charge"): R(Q) = (V_C/20(Q) - V_rate(Q)) / I
# at the same discharged charge Q, for the measured 1C and 2C records and for the truth DFN run on
# the same currents (`simulate --protocol csv:RECORD`, the DFN's own C/20 as its reference). Then a
# bound for every model whose overpotential is I x R(Q) with R independent of the rate: the measured
# R(Q) of one rate used as the model of the other, scored as whole-record RMSE against the measured
# voltage. A measurement, not a test.
#
# Usage: scripts/rate-resistance-aboutenergy.sh [OUT_DIR]   (default out/rate-resistance)
# Environment: BMSSIM=path to use a given binary instead of `./bms sim`; SHARED=path of ../shared.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out=${1:-$root/out/rate-resistance}
shared=$(cd "${SHARED:-$root/../shared}" && pwd)
data=$shared/data/aboutenergy-lfp18650
if [ -n "${BMSSIM:-}" ]; then sim=("$BMSSIM"); else sim=("$root/bms" sim); fi
mkdir -p "$out"
for r in 1C 2C Co20; do
  "${sim[@]}" simulate --cell aboutenergy --protocol "csv:$data/LFP_25degC_$r.csv" --quiet \
    --out "$out/dfn_$r" > /dev/null
done
/usr/bin/python3 - "$out" "$data" <<'PY'
import bisect, csv, math, sys
out, data = sys.argv[1:]
def record(path, tk, ik, vk):
    rows = list(csv.DictReader(open(path)))
    t = [float(x[tk]) for x in rows]; i = [float(x[ik]) for x in rows]; v = [float(x[vk]) for x in rows]
    q = [0.0]
    for k in range(1, len(t)): q.append(q[-1] + abs(i[k]) * (t[k] - t[k - 1]) / 3600.0)
    return q, v
def at(qv, x):
    q, v = qv
    k = bisect.bisect_left(q, x)
    if k <= 0: return v[0]
    if k >= len(q): return float("nan")
    return v[k - 1] + (v[k] - v[k - 1]) * (x - q[k - 1]) / (q[k] - q[k - 1])
amps = {"1C": 2.0, "2C": 4.0}
meas = {r: record(f"{data}/LFP_25degC_{r}.csv", "Time [s]", "I[A]", "U[V]") for r in ("1C", "2C", "Co20")}
dfn = {r: record(f"{out}/dfn_{r}/truth.csv", "t_s", "current_a", "voltage_v") for r in ("1C", "2C", "Co20")}
def resistance(src, r, x): return 1e3 * (at(src["Co20"], x) - at(src[r], x)) / amps[r]
grid = [0.05, 0.5, 1.0, 1.2, 1.4, 1.6, 1.7, 1.8, 1.85, 1.9]
print("Apparent resistance R(Q) = (V_C/20(Q) - V(Q)) / I in mohm, at discharged charge Q (Ah)")
print("| Q (Ah) | " + " | ".join(f"{x:g}" for x in grid) + " |")
print("|---|" + "---|" * len(grid))
for r in ("1C", "2C"):
    for name, src in (("measured", meas), ("DFN", dfn)):
        print(f"| {r} {name} | " + " | ".join("-" if math.isnan(y := resistance(src, r, x)) else f"{y:.0f}" for x in grid) + " |")
# Bound: model(rate b) = V_C/20,measured(Q) - I_b x R_a(Q), R_a measured at the other rate a;
# beyond the end of rate a's record its last R is held.
def bound(a, b, q_split=1.6):
    qa = meas[a][0]
    ra = [resistance(meas, a, x) for x in qa]
    last = next(y for y in reversed(ra) if not math.isnan(y))
    parts = {"all": [0.0, 0], "plateau": [0.0, 0], "end": [0.0, 0]}
    for x, v in zip(*meas[b]):
        r_a = at((qa, ra), x)
        if math.isnan(r_a): r_a = last
        e = 1e3 * (at(meas["Co20"], x) - amps[b] * r_a / 1e3 - v)
        for key in ("all", "plateau" if x < q_split else "end"):
            parts[key][0] += e * e; parts[key][1] += 1
    return {k: math.sqrt(s / n) if n else float("nan") for k, (s, n) in parts.items()}
print()
print("Bound for a rate-independent R(Q): the measured R(Q) of one rate as the model of the other")
print("| predicted record | R(Q) from | whole-record RMSE mV | Q < 1.6 Ah | Q >= 1.6 Ah |")
print("|---|---|---|---|---|")
for a, b in (("1C", "2C"), ("2C", "1C")):
    s = bound(a, b)
    print(f"| {b} | {a} | {s['all']:.1f} | {s['plateau']:.1f} | {s['end']:.1f} |")
with open(f"{out}/resistance.dat", "w") as f:
    f.write("# Q_ah R_1C_measured R_2C_measured R_1C_dfn R_2C_dfn (mohm)\n")
    for k in range(5, 196):
        x = k / 100.0
        f.write(f"{x:.2f} " + " ".join(f"{resistance(src, r, x):.2f}" for src in (meas, dfn) for r in ("1C", "2C")
                                       ).replace("nan", "NaN") + "\n")
PY
cat > "$out/plot.gp" <<GP
set terminal pngcairo size 900,500 font ",10"
set output "$out/rate_resistance_aboutenergy.png"
set title "About:Energy LFP 18650 (CC BY-SA 4.0, (c) About:Energy): (V_{C/20} - V) / I at the same discharged charge"
set xlabel "discharged charge Q (Ah)"; set ylabel "apparent resistance (mohm)"; set logscale y; set yrange [30:1000]
set key top left
plot "$out/resistance.dat" u 1:2 w l lw 2 lc rgb "black" t "measured 1C", "" u 1:3 w l lw 2 dt 2 lc rgb "black" t "measured 2C", \
     "" u 1:4 w l lw 2 lc rgb "blue" t "DFN 1C", "" u 1:5 w l lw 2 dt 2 lc rgb "blue" t "DFN 2C"
GP
gnuplot "$out/plot.gp"
echo "plot: $out/rate_resistance_aboutenergy.png"
