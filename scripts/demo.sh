#!/usr/bin/env bash
# ./bms demo: the truth model through 5 CCCV cycles of the paper cell, with plots.
# (The host-in-the-loop demo of issue 4 replaces this once the firmware model is wired in.)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="$root/out/demo"
mkdir -p "$out"
"$root/build/host/host_sim/bmssim" simulate --cell paper --protocol cccv --cycles 5 --noise-v-mv 0.02 --out "$out"
gnuplot <<GP
set datafile separator ','
set terminal pngcairo size 1200,800 noenhanced
set output '$out/truth.png'
set multiplot layout 2,1 title 'Paper cell, 5 CCCV cycles at 2.5 A (truth model)'
set ylabel 'voltage (V)'; set grid
plot '$out/truth.csv' every 25 using 1:5 with lines title 'terminal voltage'
set ylabel 'film resistance (ohm m^2)'; set xlabel 'time (s)'
plot '$out/truth.csv' every 25 using 1:8 with lines title 'true R_film'
unset multiplot
GP
cat > "$out/report.md" <<MD
# Demo: truth model, paper cell, 5 CCCV cycles

![voltage and film resistance](truth.png)

Data: truth.csv (contract columns), summary.json (film growth per cycle, solver statistics).
Made by \`./bms demo\`.
MD
echo "demo: wrote $out (truth.csv, summary.json, truth.png, report.md)"
