#!/usr/bin/env bash
# Replays the host's frames of a recorded host-in-the-loop can.log into a fresh firmware
# process and records its answers. Run where vcan is up (inside scripts/vcan-run.sh); compare
# with hil_check.py --replay afterwards.
#
# usage: hil_replay.sh FIRMWARE CAN_LOG OUT_DIR
# Paced by the firmware's acknowledgements (tests/cli/hil_replay.py): one tick's host frames
# are sent, then the replay waits for the firmware's BMS_Status answers before it sends the
# next tick's, so a slow or loaded machine makes the replay slower, never different. (The
# earlier canplayer replay at a fixed 1 ms per measurement lost 8 283 of 217 938 frames on a
# machine whose two cores were busy.)
# Writes OUT_DIR/replay_in.log (the host frames replayed), OUT_DIR/replay_out.log (candump -L
# of the firmware's frames, ids 0x200-0x2FF) and OUT_DIR/replay.txt (counts, wall time).
set -euo pipefail
fw="$1"; log="$2"; out="$3"
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
iface=vcan0
mkdir -p "$out"
grep -E '^\(.* 1[0-9A-Fa-f]{2}#' "$log" > "$out/replay_in.log" || true
rm -f "$out/replay.nvm" "$out/fw.ready"
"$fw" --can "$iface" --lockstep --nvm "$out/replay.nvm" > "$out/fw.ready" 2> "$out/fw.stderr" &
fw_pid=$!
trap 'kill -TERM "$fw_pid" 2>/dev/null || true' EXIT
for _ in $(seq 200); do grep -q ready "$out/fw.ready" 2>/dev/null && break; sleep 0.05; done
grep -q ready "$out/fw.ready" || { echo "hil_replay: firmware not ready"; cat "$out/fw.stderr"; exit 1; }
rc=0
/usr/bin/python3 "$here/hil_replay.py" "$iface" "$log" "$out/replay_out.log" | tee "$out/replay.txt" || rc=$?
kill -TERM "$fw_pid"; wait "$fw_pid" || true
trap - EXIT
exit "$rc"
