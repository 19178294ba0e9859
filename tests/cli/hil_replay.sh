#!/usr/bin/env bash
# Replays the host's frames of a recorded host-in-the-loop can.log with can-utils' canplayer
# into a fresh firmware process and records its answers with candump. Run where vcan is up
# (inside scripts/vcan-run.sh); compare with hil_check.py --replay afterwards.
#
# usage: hil_replay.sh FIRMWARE CAN_LOG OUT_DIR [GAP_MS]
#   GAP_MS  absent or 0: canplayer -t (as fast as it can send; the firmware's 8 MiB socket
#           buffer queues what it has not processed yet). N > 0: the log's timestamps are
#           rewritten to one measurement every N ms and canplayer keeps that pace (for logs
#           longer than the buffer holds; N = 200 is real time).
# Writes OUT_DIR/replay_in.log (what was replayed), OUT_DIR/replay_out.log (candump -L of the
# firmware's frames, ids 0x200-0x2FF) and OUT_DIR/replay.txt (frame counts, wall time).
set -euo pipefail
fw="$1"; log="$2"; out="$3"; gap_ms="${4:-0}"
iface=vcan0
mkdir -p "$out"
# Only the host's frames (ids 0x1xx): the firmware answers them again.
awk -v gap="$gap_ms" '$0 ~ /^\(/ && $3 ~ /^1[0-9A-Fa-f][0-9A-Fa-f]#/ {
  if (gap > 0) { printf "(%.6f) %s %s\n", 1700000000 + n * gap / 1000.0, $2, $3 } else print; n++ }' \
  "$log" > "$out/replay_in.log"
sent=$(wc -l < "$out/replay_in.log")
ticks=$(grep -c ' 110#' "$out/replay_in.log" || true)
expect=$((ticks * 6))  # Estimate1-3, Health, RxStats, Status per tick
rm -f "$out/replay.nvm" "$out/fw.ready"
"$fw" --can "$iface" --lockstep --nvm "$out/replay.nvm" > "$out/fw.ready" &
fw_pid=$!
for _ in $(seq 100); do grep -q ready "$out/fw.ready" 2>/dev/null && break; sleep 0.05; done
grep -q ready "$out/fw.ready" || { echo "hil_replay: firmware not ready"; exit 1; }
# candump's own buffer is enlarged too; -T ends it after 5 s of silence if frames are missing.
candump -L -r 33554432 -n "$expect" -T 5000 "$iface,200:700" > "$out/replay_out.log" &
dump_pid=$!
sleep 0.3
t0=$(date +%s.%N)
if [ "$gap_ms" = 0 ]; then canplayer -t -I "$out/replay_in.log"; else canplayer -I "$out/replay_in.log"; fi
wait "$dump_pid" || true
t1=$(date +%s.%N)
kill -TERM "$fw_pid"; wait "$fw_pid" || true
got=$(wc -l < "$out/replay_out.log")
echo "frames_replayed=$sent ticks=$ticks answers_expected=$expect answers_recorded=$got gap_ms=$gap_ms wall_s=$(echo "$t1 - $t0" | bc)" \
  | tee "$out/replay.txt"
