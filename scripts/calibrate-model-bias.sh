#!/usr/bin/env bash
# Design-time calibration of the firmware's reduced model: its voltage bias in CC charge per
# ampere over the ticks the best profile learns from (after its warm-up), against a converged DFN (40/40 volumes, rtol 1e-9) of the *nominal* paper cell, with
# the nominal film, growth law and inventory (no --set: nothing of any cell in use).
# Prints the value for firmware/include/bms/fw/model/reduced_model_bias.hpp (kPaperReducedModelBiasOhm).
# Usage: scripts/calibrate-model-bias.sh [OUT_DIR]   (about 10 s)
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="${1:-$root/out/calibrate-model-bias}"
bmssim="$root/build/host/host_sim/bmssim"
[[ -x "$bmssim" ]] || { echo "calibrate-model-bias: build first (./bms build host)" >&2; exit 1; }
mkdir -p "$out"
"$bmssim" simulate --cell paper --cycles 3 --points 40 --radial 40 --rtol 1e-9 --quiet --out "$out/nominal-fine"
# The nominal cell's own film and law, learning off, no bias: z is the model's bias.
"$bmssim" estimate --data "$out/nominal-fine/truth.csv" --model reduced --settings best --no-learning \
  --model-bias-ohm 0 --quiet --out "$out/held"
python3 - "$out/held" <<'PY'
import csv, json, statistics, sys
# The same warm-up as the profile's learning: the bias of the ticks it learns from.
warmup_s = json.load(open(sys.argv[1] + "/summary.json"))["options"]["warmup_s"]
ratios, start = [], None
for r in csv.DictReader(open(sys.argv[1] + "/estimates.csv")):
    if r["mode"] != "cc_charge":
        start = None
        continue
    t = float(r["t_s"])
    start = t if start is None else start
    i = float(r["model_current_a"])
    if t - start > warmup_s and i < 0:
        ratios.append(float(r["z_v"]) / -i)
print(f"kPaperReducedModelBiasOhm = {statistics.median(ratios):.6e}  # median over {len(ratios)} CC-charge ticks "
      f"after {warmup_s:g} s")
PY
