#!/usr/bin/env bash
# The augmented cell on the About:Energy LFP 18650 records (docs/results/diagnosis.md, "The
# augmented cell"): `diagnose` cross-validated on the 1C, 2C and C/20 discharges (each record
# scored with the parameters fitted on the other two) writes the augmented cell
# (--write-cell, --write-cell-partial: the best combination reached even when unexplained);
# then per record `simulate --protocol csv:RECORD` and `estimate --model reduced --no-learning`
# (the firmware estimator's model; one discharge has no charge to learn in, and C/20 is logged
# every 10 s, too coarse to learn) with the plain cell and with the augmented one. Prints the whole-record RMSE of
# each against the measured voltage and plots each record's residual, plain DFN beside the
# augmented cell (gnuplot PNGs in OUT_DIR). A measurement, not a test.
#
# Usage: scripts/augmented-cell-aboutenergy.sh [OUT_DIR] [-- extra diagnose options]
#        (default out/augmented-aboutenergy; an existing OUT_DIR/diag is reused)
# Environment: BMSSIM=path to use a given binary instead of `./bms sim`;
#              SHARED=path of ../shared (default: beside the repository);
#              CANDIDATES=--candidates list (default: the effects a cell file can carry).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out=$root/out/augmented-aboutenergy
if [ "$#" -gt 0 ] && [ "$1" != "--" ]; then out=$1; shift; fi
[ "$#" -gt 0 ] && [ "$1" = "--" ] && shift
extra=("$@")
shared=$(cd "${SHARED:-$root/../shared}" && pwd)
data=$shared/data/aboutenergy-lfp18650
if [ -n "${BMSSIM:-}" ]; then sim=("$BMSSIM"); else sim=("$root/bms" sim); fi
candidates=${CANDIDATES:-contact_resistance,hysteresis,thermal,particle_size,diffusivity_positive,diffusivity_negative,conductivity,electrolyte_diffusivity,i0_positive,i0_negative}
records=(1C:LFP_25degC_1C.csv 2C:LFP_25degC_2C.csv C20:LFP_25degC_Co20.csv)
mkdir -p "$out"
if [ ! -f "$out/cell/cell.bpx.json" ]; then
  args=()
  for r in "${records[@]}"; do args+=(--data "$data/${r#*:}"); done
  /usr/bin/time -f "%e s wall, %U s user" -o "$out/diag_time" \
    "${sim[@]}" diagnose "${args[@]}" --cell aboutenergy --candidates "$candidates" --open-gain 0 "${extra[@]}" \
    --write-cell "$out/cell" --write-cell-partial --out "$out/diag" 2> "$out/diag.log"
fi
for r in "${records[@]}"; do
  name=${r%%:*} file=$data/${r#*:}
  for cell in plain aug; do
    c=aboutenergy
    [ "$cell" = aug ] && c=$out/cell/cell.bpx.json
    [ -f "$out/sim_${cell}_$name/truth.csv" ] ||
      "${sim[@]}" simulate --cell "$c" --protocol "csv:$file" --quiet --out "$out/sim_${cell}_$name"
    [ -f "$out/est_${cell}_$name/estimates.csv" ] ||
      "${sim[@]}" estimate --data "$file" --cell "$c" --model reduced --no-learning --quiet --out "$out/est_${cell}_$name" > /dev/null
  done
done
/usr/bin/python3 - "$out" "$data" <<'PY'
import csv, json, math, os, sys
out, data = sys.argv[1:]
recs = [("1C", "LFP_25degC_1C.csv"), ("2C", "LFP_25degC_2C.csv"), ("C20", "LFP_25degC_Co20.csv")]
def rows(p): return list(csv.DictReader(open(p)))
def rms(x): return math.sqrt(sum(v * v for v in x) / len(x)) if x else float("nan")
w = json.load(open(os.path.join(out, "diag", "summary.json")))
print("| record | DFN plain RMSE mV | DFN augmented RMSE mV | firmware z_v RMS plain mV | firmware z_v RMS augmented mV |")
print("|---|---|---|---|---|")
for name, f in recs:
    meas = rows(os.path.join(data, f))
    t = [float(r["Time [s]"]) for r in meas]
    v = [float(r["U[V]"]) for r in meas]
    res = {}
    for cell in ("plain", "aug"):
        s = rows(os.path.join(out, f"sim_{cell}_{name}", "truth.csv"))
        n = min(len(s), len(v))
        # The model stops at its voltage limit: the rest is scored with its last residual, as diagnose does.
        r = [1e3 * (float(s[min(k, len(s) - 1)]["voltage_v"]) - v[k]) for k in range(len(v))]
        res[cell] = r
        e = rows(os.path.join(out, f"est_{cell}_{name}", "estimates.csv"))
        res[cell + "_z"] = [1e3 * float(x["z_v"]) for x in e if x["z_v"] not in ("", "nan")]
    with open(os.path.join(out, f"residual_{name}.csv"), "w") as fh:
        fh.write("t_s,residual_plain_mv,residual_aug_mv\n")
        for k in range(len(v)):
            fh.write(f"{t[k]:.3f},{res['plain'][k]:.4f},{res['aug'][k]:.4f}\n")
    print(f"| {name} | {rms(res['plain']):.2f} | {rms(res['aug']):.2f} | {rms(res['plain_z']):.2f} | {rms(res['aug_z']):.2f} |")
wc = w.get("write_cell", {})
print()
bp = w.get("best_partial", {})
print(f"answer: {w['effect']}; held-out (each record fitted on the others, pooled) {w['heldout_before_mv']:.2f} mV plain, "
      f"best reached {bp.get('heldout_mv', w['heldout_after_mv']):.2f} mV ({', '.join(bp.get('effects', [])) or w['effects']})")
print(f"cell: {wc.get('note', '')}")
PY
cat > "$out/plots.gp" <<'GP'
set datafile separator ','
set terminal pngcairo size 1200,700 noenhanced
set grid
set key top left
set xlabel 'time (s)'
set ylabel 'model - measured (mV)'
do for [r in "1C 2C C20"] {
  set output 'residual_'.r.'.png.tmp'
  set title 'About:Energy LFP 18650, '.r.' discharge: residual of the plain DFN and of the augmented cell (simulate on the measured current)'
  plot 'residual_'.r.'.csv' skip 1 using 1:2 with lines lw 2 lc rgb '#888888' title 'plain DFN (BPX)', \
       '' skip 1 using 1:3 with lines lw 2 lc rgb 'red' title 'augmented cell (diagnose --write-cell)'
}
GP
(cd "$out" && gnuplot plots.gp && for r in 1C 2C C20; do mv "residual_$r.png.tmp" "residual_$r.png"; done)
