#!/usr/bin/env bash
# Host-in-the-loop acceptance (issue 4): one paper CCCV cycle in lock-step over vcan inside a
# kernel with CAN (scripts/vcan-run.sh), twice; then the DBC/python-can client check, the
# offline-equality check and determinism. (A canplayer replay check is not here yet: replayed
# into UML without flow control, the firmware's socket loses frames; see issue 4's notes.)
# usage: hil_test.sh BMSSIM SOURCE_DIR WORK_DIR. Exit 77 (skipped) when no vcan backend works.
set -euo pipefail
bmssim="$1"; src="$2"; work="$3"
if ! "$src/scripts/vcan-run.sh" --probe >/dev/null 2>&1; then
  echo "SKIP: no kernel with vcan available (scripts/vcan-run.sh --probe)"; exit 77
fi
rm -rf "$work"; mkdir -p "$work"
"$bmssim" hil --bus uml --cycles 1 --quiet --out "$work/a"
"$bmssim" hil --bus uml --cycles 1 --quiet --out "$work/b"
"$bmssim" estimate --data "$work/a/truth.csv" --quiet --out "$work/offline"
/usr/bin/python3 "$src/tests/cli/hil_check.py" "$src/firmware/can/bms.dbc" "$work/a" "$work/offline" "$work/b"
