#!/usr/bin/env bash
# bmssim hil --fault: a bad spec exits 2 with one line naming --fault and the item, before
# any bus access (so this runs without vcan); likewise bms-firmware's numeric options.
# usage: hil_fault_bad_input_test.sh BMSSIM WORK_DIR [FIRMWARE]
set -uo pipefail
bmssim="$1"; work="$2"; fw="${3:-}"
rm -rf "$work"; mkdir -p "$work"
trap 'st=$?; [ "$st" -eq 0 ] && rm -rf "$work"; exit "$st"' EXIT  # kept only when the test fails
fail=0
check() {  # SPEC EXPECTED_TEXT
  local err rc
  err="$("$bmssim" hil --bus vcan0 --quiet --fault "$1" --out "$work/o" 2>&1 >/dev/null)"; rc=$?
  if [ "$rc" -ne 2 ] || [ "$(printf '%s\n' "$err" | wc -l)" -ne 1 ] || [[ "$err" != *"--fault"*"$2"* ]]; then
    echo "FAIL --fault '$1': exit $rc, message: $err"; fail=1
  else
    echo "PASS --fault '$1': $err"
  fi
  [ ! -e "$work/o/summary.json" ] || { echo "FAIL --fault '$1' left a summary.json"; fail=1; }
}
check "drop=2" "probability"
check "drop=x" "not a number"
check "jitter=0.1" "unknown fault"
check "drop" "KEY=VALUE"
check "burst=100" "START:TICKS"
check "burst=100:0" "at least 1 tick"
check "kill=2.5:10" "whole number"
check "drop=0.6,crc=0.6" "more than 1"
check "stale=charging+5:10" "not a mode"
check "burst=99999999:10" "does not end before"
check "kill=cc_discharge+100:10,seed=-1" "seed"
fw_check() {  # ARGS... ; the last word of the message must name the option
  local err rc opt="$1"
  err="$("$fw" --can vcan0 --lockstep "$@" 2>&1 >/dev/null)"; rc=$?
  if [ "$rc" -ne 2 ] || [[ "$err" != *"$opt"* ]]; then
    echo "FAIL bms-firmware $*: exit $rc, message: $err"; fail=1
  else
    echo "PASS bms-firmware $*: $(printf '%s' "$err" | head -1)"
  fi
}
if [ -n "$fw" ]; then
  fw_check --persist-every-s -1
  fw_check --persist-every-s abc
  fw_check --rcvbuf-bytes 10
  fw_check --flash-endurance-cycles 5
  fw_check --flash-lifetime-years nan
  fw_check --h 0
fi
exit $fail
