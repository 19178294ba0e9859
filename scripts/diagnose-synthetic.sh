#!/usr/bin/env bash
# What diagnose must show, synthetic part: for each candidate effect at a realistic size
# (models.md section 5) and for no effect, make one CCCV cycle of data with the effect
# undeclared, run `bmssim diagnose` on it, and print the table of docs/results/diagnosis.md.
#
# Usage: scripts/diagnose-synthetic.sh [OUT_DIR]      (default out/diagnose-synthetic)
# Environment: BMSSIM=path to use a given binary instead of `./bms sim`;
#              CELL=paper|aboutenergy (default paper); CASES="name=value ..." to run a subset.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out=${1:-$root/out/diagnose-synthetic}
cell=${CELL:-paper}
cases=${CASES:-"none=0 contact_resistance=0.001 hysteresis=0.015 current_offset=0.01 current_gain=0.01 thermal=0.05"}
if [ -n "${BMSSIM:-}" ]; then sim=("$BMSSIM"); else sim=("$root/bms" sim); fi
mkdir -p "$out"
for c in $cases; do
  name=${c%%=*}
  echo "== $c" >&2
  effect=()
  [ "$name" != none ] && effect=(--effect "$c")
  nice -n 10 "${sim[@]}" simulate --cell "$cell" --protocol cccv --cycles 1 "${effect[@]}" --quiet --out "$out/$name/data"
  nice -n 10 "${sim[@]}" diagnose --data "$out/$name/data/truth.csv" --cell "$cell" --out "$out/$name/diagnosis" \
    2> "$out/$name/diagnose.log" || { echo "diagnose failed for $c: $(tail -n 1 "$out/$name/diagnose.log")" >&2; continue; }
done
/usr/bin/python3 - "$out" $cases <<'PY'
import json, sys, os
out, cases = sys.argv[1], sys.argv[2:]
keys = {"contact_resistance": "contact_resistance_ohm", "hysteresis": "hysteresis_v",
        "current_offset": "current_offset_a", "current_gain": "current_gain", "thermal": "thermal_h_w_per_k"}
print("| injected | diagnosed | estimated | error % | RMSE before mV | RMSE after mV | after/before | max abs before mV | max abs after mV | runner-up (score mV) | result |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
for c in cases:
    name, value = c.split("=")
    path = os.path.join(out, name, "diagnosis", "summary.json")
    if not os.path.exists(path):
        print(f"| {c} | (failed) | | | | | | | | | fail |"); continue
    s = json.load(open(path))
    est = s["parameters"].get(keys.get(name, ""), None)
    err = 100 * (est - float(value)) / float(value) if est is not None and float(value) != 0 else None
    ratio = s["rmse_after_mv"] / s["rmse_before_mv"] if s["rmse_before_mv"] > 0 else 0
    ranked = sorted([x for x in s["candidates"] if x.get("score") is not None and x["effect"] not in ("none", s["effect"])], key=lambda x: x["score"])
    ru = f'{ranked[0]["effect"]} ({ranked[0]["score"]:.3f})' if ranked else "-"
    if name == "none":
        ok = s["effect"] == "none"
    else:
        ok = s["effect"] == name and err is not None and abs(err) <= 20 and ratio <= 0.2
    est_s = f"{est:.6g}" if est is not None else "-"
    err_s = f"{err:+.1f}" if err is not None else "-"
    print(f'| {c} | {s["effect"]} | {est_s} | {err_s} | '
          f'{s["rmse_before_mv"]:.3f} | {s["rmse_after_mv"]:.3f} | {ratio:.3f} | {s["max_abs_before_mv"]:.2f} | '
          f'{s["max_abs_after_mv"]:.2f} | {ru} | {"pass" if ok else "FAIL"} |')
PY
