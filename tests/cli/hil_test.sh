#!/usr/bin/env bash
# Host-in-the-loop acceptance (issues 4 and 8 item 3), one guest boot: inside a kernel with
# vcan (scripts/vcan-run.sh) tests/cli/hil_inside.sh runs two clean lock-step cycles, a
# replay paced by the firmware's answers, a run with every bus fault, a short real-time run,
# a failed run and a host killed mid-run; then, outside,
# the DBC/python-can client check, the offline-equality, determinism and replay checks
# (hil_check.py) and the fault and real-time checks (hil_fault_check.py).
# usage: hil_test.sh BMSSIM SOURCE_DIR WORK_DIR [FIRMWARE [FRAMES_CHECK]]. Exit 77 (skipped) when no vcan backend works.
set -euo pipefail
bmssim="$1"; src="$2"; work="$3"
fw="${4:-$(dirname "$(dirname "$bmssim")")/apps/bms-firmware}"
frames_check="${5:-$(dirname "$(dirname "$bmssim")")/tests/cli/hil_frames_check}"
if ! "$src/scripts/vcan-run.sh" --probe >/dev/null 2>&1; then
  echo "SKIP: no kernel with vcan available (scripts/vcan-run.sh --probe)"; exit 77
fi
for t in candump; do
  command -v "$t" >/dev/null || { echo "SKIP: $t (can-utils) not installed: scripts/install-deps.sh can"; exit 77; }
done
rm -rf "$work"; mkdir -p "$work"
trap 'st=$?; [ "$st" -eq 0 ] && rm -rf "$work"; exit "$st"' EXIT  # kept only when the test fails
"$src/scripts/vcan-run.sh" -- bash "$src/tests/cli/hil_inside.sh" "$bmssim" "$fw" "$src" "$work"
"$bmssim" estimate --data "$work/a/truth.csv" --quiet --out "$work/offline"
rc=0
/usr/bin/python3 "$src/tests/cli/hil_check.py" "$src/firmware/can/bms.dbc" "$work/a" "$work/offline" "$work/b" \
  --replay "$work/replay" --frames-check "$frames_check" 2> >(grep -v 'is not supported' >&2) || rc=1
/usr/bin/python3 "$src/tests/cli/hil_fault_check.py" "$work/a" "$work/faults" "$work/realtime" || rc=1
# HOST_Temperature: one frame per tick, before the tick's measurement.
n_temp=$(grep -c ' 111#' "$work/a/can.log" || true); n_meas=$(grep -c ' 110#' "$work/a/can.log" || true)
if [ "$n_temp" -gt 0 ] && [ "$n_temp" = "$n_meas" ]; then
  echo "PASS HOST_Temperature sent with every measurement: $n_temp frames"
else
  echo "FAIL HOST_Temperature frames $n_temp, measurement frames $n_meas"; rc=1
fi
# A failed run: exit 1 and nothing that looks like an output.
if grep -q '^exit=1 truth_left=no partial_left=no ' "$work/failed.txt"; then
  echo "PASS a run whose firmware cannot start exits 1 and leaves no truth.csv: $(cat "$work/failed.txt")"
else
  echo "FAIL a failed run left output or did not exit 1: $(cat "$work/failed.txt")"; rc=1
fi
# The firmware child does not outlive its parent (PR_SET_PDEATHSIG).
if grep -q 'alive_after_parent_killed=no' "$work/orphan.txt"; then
  echo "PASS the firmware child exits when bmssim hil is SIGKILLed: $(cat "$work/orphan.txt")"
else
  echo "FAIL the firmware child outlived its parent: $(cat "$work/orphan.txt")"; rc=1
fi
exit $rc
