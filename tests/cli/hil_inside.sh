#!/usr/bin/env bash
# The part of the host-in-the-loop test that needs vcan0: run inside scripts/vcan-run.sh
# (one guest boot for all of it). usage: hil_inside.sh BMSSIM FIRMWARE SOURCE_DIR WORK_DIR
#   a/, b/     two clean lock-step runs, 1 paper CCCV cycle (equality, determinism)
#   replay/    a/can.log's host frames replayed into a fresh firmware, paced by its answers
#   faults/    one lock-step run with every bus fault (tests/cli/hil_fault_check.py)
#   realtime/  75 ticks (15 s) with the firmware's own 0.2 s timer
#   failed.txt a run whose firmware cannot start: exit 1, no truth.csv left
#   orphan.txt the host SIGKILLed mid-run: its firmware child is gone within 2 s
set -euo pipefail
bmssim="$1"; fw="$2"; src="$3"; work="$4"
at=cc_charge
# Fault times in s after the CC charge starts; the learning checks need them after the best
# profile's 900 s warm-up (make_config.hpp).
# The clean runs at 15 C with a noisy, offset temperature sensor: the firmware's estimate equals
# the offline one only if HOST_Temperature carried the measured temperature to the model.
tcell=(--set temperature_k=288.15 --noise-t-k 0.2 --effect temperature_offset=0.3)
"$bmssim" hil --bus vcan0 --cycles 1 "${tcell[@]}" --quiet --out "$work/a"
"$bmssim" hil --bus vcan0 --cycles 1 "${tcell[@]}" --quiet --out "$work/b"
bash "$src/tests/cli/hil_replay.sh" "$fw" "$work/a/can.log" "$work/replay"
"$bmssim" hil --bus vcan0 --cycles 1 --quiet --out "$work/faults" --fault \
  "drop=0.01,dup=0.01,reorder=0.01,crc=0.01,length=0.01,unknown=0.01,kill=$at+600:25,stale=$at+1000:10,range=$at+1200:5,nan=$at+1300:5,burst=$at+1500:20,busdown=$at+1800:15,seed=3"
"$bmssim" hil --bus vcan0 --realtime --max-ticks 75 --quiet --out "$work/realtime"

# A short measured profile (2 minutes at rest) for the two process checks below.
awk 'BEGIN { print "Time [s],I[A],U[V]"; for (k = 0; k <= 600; k++) printf "%.1f,0,3.3\n", k * 0.2 }' > "$work/rest.csv"
rc=0
"$bmssim" hil --bus vcan0 --protocol "csv:$work/rest.csv" --firmware /bin/false --quiet --out "$work/failed" \
  2> "$work/failed.err" || rc=$?
echo "exit=$rc truth_left=$([ -e "$work/failed/truth.csv" ] && echo yes || echo no)" \
  "partial_left=$(compgen -G "$work/failed.partial*" >/dev/null && echo yes || echo no) message=$(head -c 200 "$work/failed.err" | tr '\n' ' ')" \
  > "$work/failed.txt"

"$bmssim" hil --bus vcan0 --realtime --protocol "csv:$work/rest.csv" --quiet --out "$work/orphan" 2>/dev/null &
host=$!
child_of() {  # the pid whose parent is $1 and whose command is bms-firmware
  for s in /proc/[0-9]*/stat; do
    read -r pid comm _ ppid _ < "$s" 2>/dev/null || continue
    [ "$ppid" = "$1" ] && [ "$comm" = "(bms-firmware)" ] && { echo "$pid"; return; }
  done
  return 0
}
fw_pid=""
for _ in $(seq 200); do fw_pid=$(child_of "$host"); [ -n "$fw_pid" ] && break; sleep 0.1; done
kill -KILL "$host"; wait "$host" 2>/dev/null || true
alive=unknown
if [ -n "$fw_pid" ]; then
  alive=yes
  for _ in $(seq 20); do kill -0 "$fw_pid" 2>/dev/null || { alive=no; break; }; sleep 0.1; done
  [ "$alive" = yes ] && kill -KILL "$fw_pid"
fi
echo "firmware_pid=${fw_pid:-none} alive_after_parent_killed=$alive" > "$work/orphan.txt"
