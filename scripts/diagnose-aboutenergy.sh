#!/usr/bin/env bash
# What diagnose must show, measured part: `bmssim diagnose` on the About:Energy LFP 18650 C/20,
# 1C and 2C discharges with the BPX parameters, each case alone and the three together
# (fit on the 1C case, validate on C/20 and 2C: the cross-validated figure). Prints the
# table of docs/results/diagnosis.md.
#
# Usage: scripts/diagnose-aboutenergy.sh [OUT_DIR]     (default out/diagnose-aboutenergy)
# Environment: BMSSIM=path to use a given binary instead of `./bms sim`;
#              SHARED=path of ../shared (default: beside the repository);
#              CANDIDATES=list for --candidates (default: all five effects and particle_size,
#              the cathode particle-size spread, which `all` leaves out).
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out=${1:-$root/out/diagnose-aboutenergy}
shared=$(cd "${SHARED:-$root/../shared}" && pwd)
data=$shared/data/aboutenergy-lfp18650
bpx=$data/lfp_18650_cell_BPX.json
if [ -n "${BMSSIM:-}" ]; then sim=("$BMSSIM"); else sim=("$root/bms" sim); fi
default_candidates=contact_resistance,hysteresis,current_offset,current_gain,thermal,particle_size
mkdir -p "$out"
run() { # NAME DATA_FILES...
  local name=$1; shift
  local args=()
  for f in "$@"; do args+=(--data "$data/$f"); done
  echo "== $name" >&2
  nice -n 10 "${sim[@]}" diagnose "${args[@]}" --cell "$bpx" --candidates "${CANDIDATES:-$default_candidates}" --out "$out/$name" 2> "$out/$name.log" ||
    echo "diagnose failed for $name: $(tail -n 1 "$out/$name.log")" >&2
}
run c20 LFP_25degC_Co20.csv
run 1c LFP_25degC_1C.csv
run 2c LFP_25degC_2C.csv
run cross LFP_25degC_1C.csv LFP_25degC_Co20.csv LFP_25degC_2C.csv
/usr/bin/python3 - "$out" <<'PY'
import json, os, sys
out = sys.argv[1]
print("| run | data (role) | diagnosed | parameters | RMSE before mV | RMSE after mV | max abs before mV | max abs after mV |")
print("|---|---|---|---|---|---|---|---|")
for name in ["c20", "1c", "2c", "cross"]:
    p = os.path.join(out, name, "summary.json")
    if not os.path.exists(p):
        print(f"| {name} | (failed) | | | | | | |"); continue
    s = json.load(open(p))
    params = ", ".join(f"{k} = {v:.4g}" for k, v in s["parameters"].items()) or "-"
    for c in s["cases"]:
        print(f'| {name} | {os.path.basename(c["data"])} ({c["role"]}) | {s["effect"]} | {params} | '
              f'{c["rmse_before_mv"]:.2f} | {c["rmse_after_mv"]:.2f} | {c["max_abs_before_mv"]:.1f} | {c["max_abs_after_mv"]:.1f} |')
    print(f'| {name} | reason | {s["reason"]} | | | | | |')
    cands = ", ".join(f'{c["effect"]} {c["score"]:.2f}' if c.get("score") is not None else f'{c["effect"]} n/a'
                      for c in s["candidates"])
    print(f'| {name} | scores (held-out RMSE mV) | {cands} | | | | | |')
PY
