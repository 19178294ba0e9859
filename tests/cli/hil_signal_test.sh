#!/usr/bin/env bash
# SIGTERM/SIGINT to `bmssim hil --bus uml`: the run inside the guest kernel is stopped, the
# command exits 128 + N and leaves no DIR.partial-PID/ (truth.csv, can.log.tmp, firmware.nvm)
# and no DIR; a signal while the guest boots does the same. A run left alone still commits.
# usage: hil_signal_test.sh BMSSIM SOURCE_DIR FIRMWARE. Exit 77 (skipped) without User-Mode Linux.
set -u
bmssim=$(realpath "$1"); src="$2"; fw=$(realpath "$3")
if ! VCAN_RUN_BACKEND=uml "$src/scripts/vcan-run.sh" --probe >/dev/null 2>&1; then
  echo "SKIP: User-Mode Linux with vcan not available (scripts/vcan-run.sh --backend uml --probe)"; exit 77
fi
work=$(mktemp -d "${TMPDIR:-/tmp}/bmssim_hil_signal.XXXXXX") || exit 1
trap 'rm -rf "$work"' EXIT
cd "$work" || exit 1
failed=0
hil=("$bmssim" hil --bus uml --firmware "$fw" --cycles 1 --quiet)

# signalled NAME SIGNAL WHEN: WHEN "running" = once the run inside has written truth.csv and
# opened can.log.tmp in its staging folder (then 1 s more), else seconds after the start.
signalled() {
  local name=$1 sig=$2 when=$3 pid rc want seen="" t0
  "${hil[@]}" --out "$name" > /dev/null 2> "$name.err" & pid=$!
  if [ "$when" = running ]; then
    for _ in $(seq 600); do
      [ -e "$name.partial-$pid/can.log.tmp" ] && [ -e "$name.partial-$pid/truth.csv" ] && { seen=$(ls "$name.partial-$pid" | tr '\n' ' '); break; }
      kill -0 $pid 2>/dev/null || break
      sleep 0.1
    done
    sleep 1
  else sleep "$when"; fi
  t0=$(date +%s); kill "-$sig" $pid
  timeout 60 tail --pid=$pid -f /dev/null; wait $pid; rc=$?
  want=$((128 + $(kill -l "$sig")))
  local left
  left=$(ls -d "$name" "$name".partial-* 2>/dev/null | tr '\n' ' ')
  if [ $rc -eq $want ] && [ -z "$left" ] && { [ "$when" != running ] || [ -n "$seen" ]; } &&
     [ "$(pgrep -f "$work/$name" | wc -l)" -eq 0 ]; then
    echo "PASS $name: exit $rc $(($(date +%s) - t0)) s after SIG$sig${seen:+ (staging held: $seen)}, nothing left"
  else
    echo "FAIL $name: exit $rc (want $want), staging seen: '${seen}', left: '$left': $(tail -n 2 "$name.err" | tr '\n' ' ')"
    failed=1
  fi
}
signalled term_running TERM running
signalled int_running INT running
signalled term_booting TERM 0.5

# Left alone (a few ticks), the same command commits its folder whole.
if "${hil[@]}" --max-ticks 500 --out whole > /dev/null 2> whole.err && [ -f whole/summary.json ] && [ -f whole/can.log ] &&
   ! ls -d whole.partial-* > /dev/null 2>&1; then
  echo "PASS whole: exit 0, summary.json and can.log in place"
else echo "FAIL whole: $(tail -n 2 whole.err | tr '\n' ' ')"; failed=1; fi
exit $failed
