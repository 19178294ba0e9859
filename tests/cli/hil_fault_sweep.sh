#!/usr/bin/env bash
# Bus-fault sweep of the host-in-the-loop: one clean lock-step run and one
# run per fault kind, all in one User-Mode Linux session, then the table of
# docs/results/reliability.md ("Bus faults in the host-in-the-loop") from their summaries.
#
# usage: tests/cli/hil_fault_sweep.sh BMSSIM OUT_DIR [CYCLES] [SEED]
#   e.g. tests/cli/hil_fault_sweep.sh build/host/host_sim/bmssim out/fault-sweep 1 3
# Windows are placed 1500 s into the first CC charge (where the estimator learns), or at
# HIL_FAULT_AT (a tick number or MODE+SECONDS); HIL_EXTRA adds hil options to every run, e.g.
#   HIL_EXTRA=--beyond-paper HIL_FAULT_AT=63132 tests/cli/hil_fault_sweep.sh B out/fs-beyond 2 3
# (tick 63132 = 1500 s into the second CC charge, the first one the beyond-paper estimator learns in).
# Writes OUT_DIR/<scenario>/ (hil outputs) and OUT_DIR/table.md.
set -euo pipefail
bmssim="$(realpath "$1")"; out="$(realpath -m "$2")"; cycles="${3:-1}"; seed="${4:-3}"
src="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
at="${HIL_FAULT_AT:-cc_charge+1500}"
read -r -a extra <<< "${HIL_EXTRA:-}"
scenarios=(
  "clean|"
  "drop 1 %|drop=0.01"
  "drop 10 %|drop=0.1"
  "burst 50 ticks|burst=$at:50"
  "duplicated 1 %|dup=0.01"
  "reordered 1 %|reorder=0.01"
  "CRC corrupted 1 %|crc=0.01"
  "wrong length 1 %|length=0.01"
  "unknown id 1 %|unknown=0.01"
  "stale counter 50 ticks|stale=$at:50"
  "voltage 7 V 25 ticks|range=$at:25"
  "voltage NaN 25 ticks|nan=$at:25"
  "bus down 50 ticks|busdown=$at:50"
  "firmware killed 25 ticks|kill=$at:25"
)
mkdir -p "$out"
job="$out/sweep_inside.sh"
{
  echo "set -e"
  i=0
  for s in "${scenarios[@]}"; do
    spec="${s#*|}"
    fault=()
    [ -n "$spec" ] && fault=(--fault "$spec,seed=$seed")
    printf '%q ' "$bmssim" hil --bus vcan0 --cycles "$cycles" --quiet --out "$out/s$i" "${extra[@]}" "${fault[@]}"
    echo
    i=$((i + 1))
  done
} > "$job"
nice -n 10 "$src/scripts/vcan-run.sh" -- bash "$job"
names=()
for s in "${scenarios[@]}"; do names+=("${s%%|*}"); done
/usr/bin/python3 "$src/tests/cli/hil_fault_table.py" "$out" "${names[@]}" | tee "$out/table.md"
