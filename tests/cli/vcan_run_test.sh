#!/usr/bin/env bash
# scripts/vcan-run.sh end to end: inside the runner (host kernel, User-Mode Linux or QEMU,
# whichever --backend auto picks; VCAN_RUN_BACKEND overrides), real SocketCAN clients that
# this project did not write exchange frames over vcan0:
#   1. can-utils: cansend -> candump
#   2. python3-can: Bus.send -> another Bus.recv, and cansend -> Bus.recv
# and the runner keeps the working directory and returns the command's exit status.
# Exit 77 (ctest SKIP_RETURN_CODE) when no backend or client is installed:
# scripts/install-deps.sh can.
# usage: vcan_run_test.sh PATH/TO/scripts/vcan-run.sh
set -uo pipefail
runner="${1:?usage: vcan_run_test.sh PATH/TO/vcan-run.sh}"
runner="$(cd "$(dirname "$runner")" && pwd)/$(basename "$runner")"
[ -f "$runner" ] || { echo "FAIL: no runner at $runner"; exit 1; }
PY=/usr/bin/python3

skip() { echo "SKIP: $*"; exit 77; }
fail() { echo "FAIL: $*"; exit 1; }

command -v candump >/dev/null && command -v cansend >/dev/null \
  || skip "can-utils is not installed (scripts/install-deps.sh can)"
[ -x "$PY" ] && "$PY" -c 'import can' 2>/dev/null \
  || skip "python3-can is not installed for $PY (scripts/install-deps.sh can)"

t0=$(date +%s)
probe_out="$(bash "$runner" --probe 2>&1)"
probe_rc=$?
echo "$probe_out"
[ "$probe_rc" = 0 ] || skip "no vcan backend works here (see above)"

work="$(mktemp -d "${TMPDIR:-/tmp}/vcan-run-test.XXXXXX")"
trap 'rm -rf "$work"' EXIT

cat > "$work/inside.sh" <<'SH'
#!/bin/bash
# Runs inside the runner: results go to stdout and to files in $1.
set -u
d="$1"
ip -br link show vcan0 || { echo "no vcan0"; exit 10; }

# 1. can-utils. candump may not be listening yet when cansend first runs: send until it
#    has received one frame (it exits after -n 1).
timeout 20 candump -n 1 -L vcan0 > "$d/candump.txt" &
dump=$!
for _ in $(seq 100); do
  cansend vcan0 123#DEADBEEF || exit 11
  sleep 0.1
  kill -0 "$dump" 2>/dev/null || break
done
wait "$dump" || { echo "candump failed"; exit 12; }
echo "candump: $(cat "$d/candump.txt")"

# 2. python3-can: one Bus sends, another receives; then cansend -> Bus.recv.
/usr/bin/python3 - "$d/python.txt" <<'PY' || exit 13
import subprocess, sys
import can

out = open(sys.argv[1], "w")
with can.Bus(interface="socketcan", channel="vcan0") as rx, \
     can.Bus(interface="socketcan", channel="vcan0") as tx:
    sent = can.Message(arbitration_id=0x1A5, data=bytes([0xCA, 0xFE, 0x00, 0x42]),
                       is_extended_id=False)
    tx.send(sent)
    got = rx.recv(timeout=5.0)
    if got is None or got.arbitration_id != 0x1A5 or bytes(got.data) != bytes(sent.data):
        print("python-can: Bus -> Bus: wrong or no frame:", got); sys.exit(1)
    print(f"python-can Bus->Bus {got.channel} {got.arbitration_id:03X}#{bytes(got.data).hex().upper()}", file=out)
    subprocess.run(["cansend", "vcan0", "12345678#0102030405060708"], check=True)
    got = rx.recv(timeout=5.0)
    if got is None or not got.is_extended_id or got.arbitration_id != 0x12345678 \
            or bytes(got.data) != bytes(range(1, 9)):
        print("python-can: cansend -> Bus: wrong or no frame:", got); sys.exit(1)
    print(f"python-can cansend->Bus {got.channel} {got.arbitration_id:08X}#{bytes(got.data).hex().upper()}", file=out)
out.close()
PY
cat "$d/python.txt"
SH
chmod +x "$work/inside.sh"

# One guest run for the CAN clients.
out="$(bash "$runner" -- "$work/inside.sh" "$work" 2>&1)"
rc=$?
echo "$out"
[ "$rc" = 0 ] || fail "the CAN clients inside the runner exited $rc"
grep -q 'vcan0 123#DEADBEEF' "$work/candump.txt" 2>/dev/null \
  || fail "candump did not record the frame cansend sent on vcan0"
grep -q '^python-can Bus->Bus vcan0 1A5#CAFE0042$' "$work/python.txt" 2>/dev/null \
  || fail "python3-can did not receive its own Bus's frame on vcan0"
grep -q '^python-can cansend->Bus vcan0 12345678#0102030405060708$' "$work/python.txt" 2>/dev/null \
  || fail "python3-can did not receive the frame cansend sent on vcan0"

# One more for the runner's contract: working directory, exit status, stdout vs stderr.
mkdir -p "$work/cwd test"
out2="$(cd "$work/cwd test" && bash "$runner" -- bash -c 'pwd; echo to-stderr >&2; exit 7' 2>"$work/stderr.txt")"
rc=$?
[ "$rc" = 7 ] || fail "exit status 7 came back as $rc"
[ "$out2" = "$work/cwd test" ] || fail "working directory inside was '$out2', not '$work/cwd test'"
grep -q '^to-stderr$' "$work/stderr.txt" || fail "stderr did not come back on stderr"

echo "vcan runner test: passed in $(( $(date +%s) - t0 )) s"
