#!/usr/bin/env bash
# How long `bmssim diagnose` takes on a 10 000 s drive cycle of the paper cell, without an
# effect and with a 2 mohm contact resistance: wall time, CPU time, peak memory, the machine's
# load before and after, and the answer (docs/results/diagnosis.md "Drive cycles and speed").
# A measurement, not a test: the numbers depend on the machine and on what else runs on it.
#
# Usage: scripts/diagnose-speed.sh [OUT_DIR] [-- extra diagnose options, e.g. --threads 1]
# Environment: BMSSIM=path to use a given binary instead of `./bms sim`.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
out=$root/out/diagnose-speed
if [ "$#" -gt 0 ] && [ "$1" != "--" ]; then out=$1; shift; fi
[ "$#" -gt 0 ] && [ "$1" = "--" ] && shift
extra=("$@")
if [ -n "${BMSSIM:-}" ]; then sim=("$BMSSIM"); else sim=("$root/bms" sim); fi
mkdir -p "$out"
"$root/scripts/drive-cycle.sh" "$out/udds10k.csv" 10000
for c in none contact; do
  effect=()
  [ "$c" = contact ] && effect=(--effect contact_resistance=0.002)
  [ -f "$out/sim_$c/truth.csv" ] ||
    "${sim[@]}" simulate --cell paper --protocol "csv:$out/udds10k.csv" --points 12 --radial 12 --rtol 1e-7 \
      --noise-v-mv 0.1 "${effect[@]}" --quiet --out "$out/sim_$c"
done
echo "| data | answer | held-out before -> after mV | wall s | CPU s (user + sys) | max RSS kB | load before | load after |"
echo "|---|---|---|---|---|---|---|---|"
for c in none contact; do
  load0=$(cut -d' ' -f1 /proc/loadavg)
  /usr/bin/time -f "%e %U %S %M" -o "$out/time_$c" \
    "${sim[@]}" diagnose --data "$out/sim_$c/truth.csv" --cell paper "${extra[@]}" --out "$out/diag_$c" \
    2> "$out/diagnose_$c.log"
  load1=$(cut -d' ' -f1 /proc/loadavg)
  read -r wall user sys rss < "$out/time_$c"
  /usr/bin/python3 - "$out/diag_$c/summary.json" "$c" "$wall" "$user" "$sys" "$rss" "$load0" "$load1" <<'PY'
import json, sys
path, c, wall, user, sys_s, rss, l0, l1 = sys.argv[1:]
s = json.load(open(path))
after = s["heldout_after_mv"] if s.get("explained") else s["heldout_before_mv"]
params = ", ".join(f"{k} = {v:.4g}" for k, v in s.get("parameters", {}).items())
answer = s["effect"] + (f" ({params})" if params else "")
data = "no effect" if c == "none" else "contact resistance 2 mohm"
print(f"| {data} | {answer} | {s['heldout_before_mv']:.3f} -> {after:.3f} | {float(wall):.1f} | "
      f"{float(user) + float(sys_s):.1f} | {rss} | {l0} | {l1} |")
PY
done
