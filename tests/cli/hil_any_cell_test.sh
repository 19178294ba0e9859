#!/usr/bin/env bash
# Host-in-the-loop on a cell other than the paper's: `bmssim hil --cell aboutenergy --lockstep`
# runs bms-firmware-aboutenergy (the About:Energy cell's generated configuration compiled in,
# CMake BMS_LINUX_FIRMWARE_CELLS) over vcan inside a kernel (scripts/vcan-run.sh); the offline
# `bmssim estimate --cell aboutenergy --model reduced` on its truth.csv must give the same film
# resistance on the bus's 1e-10 ohm m2 grid in every tick (within half a bus step), and the
# same frames byte for byte (tests/cli/hil_check.py, hil_frames_check). Before the bus: the
# paper-cell bms-firmware refuses --cell aboutenergy (exit 2, naming the cell), and hil
# refuses a cell no firmware holds.
# usage: hil_any_cell_test.sh BMSSIM SOURCE_DIR WORK_DIR PAPER_FIRMWARE FRAMES_CHECK
# Exit 77 (skipped) when no vcan backend works.
set -euo pipefail
bmssim="$1"; src="$2"; work="$3"; paper_fw="$4"; frames_check="$5"
rm -rf "$work"; mkdir -p "$work"
trap 'st=$?; [ "$st" -eq 0 ] && rm -rf "$work"; exit "$st"' EXIT  # kept only when the test fails
rc=0
set +e
"$paper_fw" --can vcan0 --lockstep --cell aboutenergy 2> "$work/refused.txt"; code=$?
set -e
if [ $code -eq 2 ] && grep -q "holds the cell 'paper'" "$work/refused.txt"; then
  echo "PASS the paper-cell bms-firmware refuses --cell aboutenergy: $(head -n 1 "$work/refused.txt")"
else
  echo "FAIL bms-firmware --cell aboutenergy: exit $code: $(head -n 1 "$work/refused.txt")"; rc=1
fi
printf 'Time [s],I[A],U[V]\n0,0,3.3\n1,0,3.3\n' > "$work/rest.csv"
set +e
"$bmssim" hil --bus vcan0 --cell "$src/../shared/data/aboutenergy-lfp18650/lfp_18650_cell_BPX.json" \
  --protocol "csv:$work/rest.csv" --quiet --out "$work/file_cell" 2> "$work/file_cell.txt"; code=$?
set -e
if [ $code -eq 2 ] && grep -q -- "--cell .*built-in cell" "$work/file_cell.txt" && [ ! -e "$work/file_cell" ]; then
  echo "PASS hil refuses a cell no firmware holds, before the bus: $(head -n 1 "$work/file_cell.txt")"
else
  echo "FAIL hil --cell FILE: exit $code: $(head -n 1 "$work/file_cell.txt")"; rc=1
fi
if ! "$src/scripts/vcan-run.sh" --probe >/dev/null 2>&1; then
  echo "SKIP: no kernel with vcan available (scripts/vcan-run.sh --probe)"; [ $rc -eq 0 ] && exit 77 || exit $rc
fi
"$src/scripts/vcan-run.sh" -- "$bmssim" hil --bus vcan0 --cell aboutenergy --lockstep --cycles 1 --quiet --out "$work/a"
"$bmssim" estimate --data "$work/a/truth.csv" --cell aboutenergy --model reduced --quiet --out "$work/offline"
/usr/bin/python3 "$src/tests/cli/hil_check.py" "$src/firmware/can/bms.dbc" "$work/a" "$work/offline" \
  --frames-check "$frames_check" 2> >(grep -v 'is not supported' >&2) || rc=1
/usr/bin/python3 - "$work/a/estimates.csv" "$work/offline/estimates.csv" <<'PY' || rc=1
import csv, sys
a = list(csv.DictReader(open(sys.argv[1])))
b = list(csv.DictReader(open(sys.argv[2])))
d = max(abs(float(x["r_film_est_ohm_m2"]) - float(y["r_film_est_ohm_m2"])) for x, y in zip(a, b))
good = len(a) == len(b) and d <= 0.5e-10
print(f"{'PASS' if good else 'FAIL'} hil --cell aboutenergy vs offline estimate: largest film difference {d:.4e} "
      f"ohm m2 over {len(a)} ticks (half a bus step: 5e-11)")
sys.exit(0 if good else 1)
PY
exit $rc
