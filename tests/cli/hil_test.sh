#!/usr/bin/env bash
# Host-in-the-loop acceptance (issues 4 and 8 item 3), one guest boot: inside a kernel with
# vcan (scripts/vcan-run.sh) tests/cli/hil_inside.sh runs two clean lock-step cycles, a
# canplayer replay, a run with every bus fault and a short real-time run; then, outside,
# the DBC/python-can client check, the offline-equality, determinism and replay checks
# (hil_check.py) and the fault and real-time checks (hil_fault_check.py).
# usage: hil_test.sh BMSSIM SOURCE_DIR WORK_DIR [FIRMWARE]. Exit 77 (skipped) when no vcan backend works.
set -euo pipefail
bmssim="$1"; src="$2"; work="$3"
fw="${4:-$(dirname "$(dirname "$bmssim")")/hal/bms-firmware}"
if ! "$src/scripts/vcan-run.sh" --probe >/dev/null 2>&1; then
  echo "SKIP: no kernel with vcan available (scripts/vcan-run.sh --probe)"; exit 77
fi
for t in canplayer candump; do
  command -v "$t" >/dev/null || { echo "SKIP: $t (can-utils) not installed: scripts/install-deps.sh can"; exit 77; }
done
rm -rf "$work"; mkdir -p "$work"
"$src/scripts/vcan-run.sh" -- bash "$src/tests/cli/hil_inside.sh" "$bmssim" "$fw" "$src" "$work"
"$bmssim" estimate --data "$work/a/truth.csv" --quiet --out "$work/offline"
rc=0
/usr/bin/python3 "$src/tests/cli/hil_check.py" "$src/firmware/can/bms.dbc" "$work/a" "$work/offline" "$work/b" \
  --replay "$work/replay" 2> >(grep -v 'is not supported' >&2) || rc=1
/usr/bin/python3 "$src/tests/cli/hil_fault_check.py" "$work/a" "$work/faults" "$work/realtime" || rc=1
exit $rc
