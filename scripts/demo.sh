#!/usr/bin/env bash
# ./bms demo: host-in-the-loop with the paper cell. The truth model (DFN + Ramadass) runs 5
# CCCV cycles of a cell that is *not* the nominal one (hidden truth parameters: film growing
# twice as fast as the nominal law, initial film 10 % high, 0.5 % less lithium) and feeds the
# firmware process (best profile: it knows the nominal cell only) over vcan0 in lock-step
# (bmssim hil --bus uml: both inside User-Mode Linux where this kernel has no CAN). Writes
# out/demo/: truth.csv, estimates.csv, can.log, summary.json, PNG figures and report.md.
# Where no kernel with vcan can be had (scripts/vcan-run.sh --probe fails), the same firmware
# core runs offline on the same data (bmssim simulate + estimate), and report.md says so.
# usage: scripts/demo.sh [--cycles N] [--out DIR]   (./bms demo builds build/host first)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="$root/out/demo"; cycles=5
while [ $# -gt 0 ]; do
  case "$1" in
    --cycles) cycles="$2"; shift 2 ;;
    --out) out="$(realpath -m "$2")"; shift 2 ;;
    *) echo "demo: unknown argument '$1' (usage: scripts/demo.sh [--cycles N] [--out DIR])" >&2; exit 2 ;;
  esac
done
bmssim="${BMSSIM:-$root/build/host/host_sim/bmssim}"
# The cell the firmware does not know (its film law, initial film and inventory differ from nominal).
hidden=(--set film_growth_scale=2 --set r_film_initial_ohm_m2=0.0037301 --set inventory_scale=0.995)
[ -x "$bmssim" ] || { echo "demo: $bmssim not built (run ./bms demo, or ./bms build)" >&2; exit 1; }
# UML, can-utils, python3-can (idempotent; a failure only means the offline fallback).
"$root/scripts/install-deps.sh" can >/dev/null 2>&1 || echo "demo: could not install the 'can' packages; trying anyway" >&2
rm -rf "$out"; mkdir -p "$out"
if "$root/scripts/vcan-run.sh" --probe >/dev/null 2>&1; then
  how="host-in-the-loop: \`bmssim hil --bus uml --cycles $cycles ${hidden[*]}\` (firmware process, best profile, fed over vcan0 inside User-Mode Linux, lock-step)"
  "$bmssim" hil --bus uml --cycles "$cycles" "${hidden[@]}" --out "$out"
else
  echo "demo: no kernel with vcan here (scripts/vcan-run.sh --probe failed; see docs/results/vcan-runner.md):" \
       "running the same firmware core offline instead of over the bus" >&2
  how="**offline fallback** (no kernel with vcan: \`scripts/vcan-run.sh --probe\` failed): \`bmssim simulate\` + \`bmssim estimate\`, the same firmware core without the bus"
  "$bmssim" simulate --cell paper --protocol cccv --cycles "$cycles" "${hidden[@]}" --out "$out/truth"
  "$bmssim" estimate --data "$out/truth/truth.csv" --out "$out"
  cp "$out/truth/truth.csv" "$out/truth.csv"
fi

# Operating-mode spans (true mode, truth.csv column 3) as shaded rectangles, like the
# paper's figures 4-5: 1 CC discharge, 2 CV discharge, 3 CC charge, 4 CV charge.
awk -F, 'NR > 1 {
    t = $1 / 3600; m = $3
    if (m != cur) { if (cur != "") emit(); cur = m; t0 = t }
    t1 = t }
  function emit(  c) {
    c = (cur == "cc_discharge") ? "#fde0c5" : (cur == "cv_discharge") ? "#f6c6c6" : \
        (cur == "cc_charge") ? "#cfe8cf" : (cur == "cv_charge") ? "#cfdcf2" : "#eeeeee"
    printf "set object rect from %.6f, graph 0 to %.6f, graph 1 fc rgb \"%s\" fs solid 1.0 noborder behind\n", t0, t1, c }
  END { if (cur != "") emit() }' "$out/truth.csv" > "$out/modes.gp"
# The last CC charge, for the magnified view (the paper's figure 5).
read -r z0 z1 < <(awk -F, 'NR > 1 && $3 == "cc_charge" { if (!in_cc) { s = $1 }; in_cc = 1; e = $1 }
  NR > 1 && $3 != "cc_charge" { in_cc = 0 } END { printf "%.6f %.6f\n", s / 3600 - 0.05, e / 3600 + 0.05 }' "$out/truth.csv")

# Growth (comma-separated, as gnuplot reads the CSVs) since the end of the first CC charge (the reference of growth_err_pct): estimate, truth,
# and what the nominal law predicts (the true growth divided by the hidden factor 2).
python3 - "$out" <<'PY'
import csv, sys
out = sys.argv[1]
rows = list(csv.DictReader(open(out + "/estimates.csv")))
ref = None
for i, r in enumerate(rows):
    if r["mode"] == "cc_charge" and (i + 1 == len(rows) or rows[i + 1]["mode"] != "cc_charge"):
        ref = i
        break
with open(out + "/growth.dat", "w") as f:
    if ref is not None:
        e0, t0 = float(rows[ref]["r_film_est_ohm_m2"]), float(rows[ref]["r_film_true_ohm_m2"])
        for r in rows[ref::10]:
            dt = float(r["r_film_true_ohm_m2"]) - t0
            f.write(f"{float(r['t_s']) / 3600:.5f},{float(r['r_film_est_ohm_m2']) - e0:.6e},{dt:.6e},{dt / 2:.6e}\n")
PY

gnuplot <<GP
set datafile separator ','
set terminal pngcairo size 1400,600 noenhanced font ',11'
set grid; set key top left opaque
set xlabel 'time (h)'
set autoscale xfix
load '$out/modes.gp'
set output '$out/film_resistance.png'
set title 'Film resistance: truth (DFN + Ramadass) and the firmware estimate (RCSI). Shaded: CC discharge, CV discharge, CC charge, CV charge'
set ylabel 'R_film (ohm m^2)'
plot '$out/estimates.csv' every 10 using (\$1/3600):6 with lines lw 2 lc rgb 'black' title 'true', \
     '' every 10 using (\$1/3600):5 with lines lw 1.5 lc rgb '#d62728' title 'estimated (firmware)'
set output '$out/film_resistance_zoom.png'
set title 'Magnified: the last constant-current charge'
set xrange [$z0:$z1]
plot '$out/estimates.csv' using (\$1/3600):6 with lines lw 2 lc rgb 'black' title 'true', \
     '' using (\$1/3600):5 with lines lw 1.5 lc rgb '#d62728' title 'estimated (firmware)'
set xrange [*:*]; set autoscale xfix
set output '$out/residual.png'
set title 'Voltage residual z = y_hat - y (model minus measured), RCSI learning ticks'
set ylabel 'z (mV)'
plot '$out/estimates.csv' using (\$1/3600):(\$4 > 0 ? \$7*1000 : 1/0) with points pt 7 ps 0.2 lc rgb '#1f77b4' title 'z'
set output '$out/growth.png'
set title 'Film growth since the end of the first CC charge: learned by the firmware vs the truth (its law is 2x the nominal)'
set ylabel 'R_film - R_film(ref) (ohm m^2)'
plot '$out/growth.dat' using 1:3 with lines lw 2 lc rgb 'black' title 'true growth', \
     '' using 1:2 with lines lw 1.5 lc rgb '#d62728' title 'learned growth (firmware)', \
     '' using 1:4 with lines lw 1 dt 2 lc rgb 'gray' title 'the nominal law would predict'
GP

/usr/bin/python3 - "$out" "$how" "${hidden[*]}" <<'PY'
import json, sys
out, how, hidden = sys.argv[1], sys.argv[2], sys.argv[3]
s = json.load(open(out + "/summary.json"))
g = s.get("growth_err_pct")
growth_err = f"{g:.1f} %" if g is not None else "n/a"
hil = s.get("hil", {})
rows = "\n".join(f"| {c['cycle']} | {c['r_film_true_end_ohm_m2']:.6g} | {c['r_film_est_end_ohm_m2']:.6g} | "
                 f"{c['r_film_err_median_pct']:.2f} | {c['r_film_err_end_pct']:.2f} |" for c in s["cycles"])
speed = (f"{hil['ticks']} ticks ({hil['sim_s']:.0f} s simulated) in {hil['wall_s']:.1f} s wall: "
         f"**{hil['sim_s_per_wall_s']:.0f} x real time**; firmware exit {hil['firmware_exit']}." if hil else "")
open(out + "/report.md", "w").write(f"""# Demo: paper cell, {len(s['cycles'])} CCCV cycles, RCSI film-resistance estimate

How: {how}. Truth: DFN + Ramadass side reaction (SUNDIALS IDA), 2.5 A CC, 0.2 s sample
time, no measurement noise (the paper's figures 4-5), a cell whose film law, initial film and
lithium inventory differ from the nominal cell's. The firmware receives voltage and
current at the bus resolution (10 uV, 0.1 mA) and answers with its estimate every tick.

![film resistance with the operating modes shaded](film_resistance.png)

![magnified: the last CC charge](film_resistance_zoom.png)

![voltage residual](residual.png)

![learned vs true growth](growth.png)

Hidden truth parameters (the firmware gets none of them: it knows the nominal cell and its own
measurements): `{hidden}`. The firmware's best profile identifies the initial film, the growth
law's gain and the lithium inventory from voltage and current (docs/results/blind.md).
growth_err_pct (growth since the end of the first CC charge, contract): **{growth_err}**.

Film-resistance error during constant-current charging (where the film is identifiable):

| cycle | true R_film at CC end (ohm m2) | estimate at CC end | median error in CC charge (%) | error at CC end (%) |
|---|---|---|---|---|
{rows}

{speed}

Files: truth.csv (truth + measured), estimates.csv (the firmware's answers), can.log
(candump format, every frame on the bus), summary.json. Made by `./bms demo`.
""")
PY
rm -f "$out/modes.gp" "$out/growth.dat"
echo "demo: wrote $out (report.md, film_resistance.png, film_resistance_zoom.png, residual.png, growth.png, estimates.csv, truth.csv, summary.json)"
