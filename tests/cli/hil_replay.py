#!/usr/bin/python3
"""Replays the host's frames of a recorded host-in-the-loop can.log into a firmware on a
SocketCAN interface, paced by the firmware's answers, and records the answers.

usage: hil_replay.py IFACE CAN_LOG OUT_LOG [--timeout-s S]

The recorded log holds, per tick, the host's frames (ids 0x1xx) followed by the firmware's
answer (ids 0x2xx, closed by BMS_Status 0x210). The replay sends one tick's host frames,
then waits until as many BMS_Status frames came back as the recording shows for that tick,
and only then sends the next tick's: flow control by the firmware's acknowledgements, so the
result does not depend on how fast the machine is (the earlier canplayer replay, paced at
1 ms per measurement, lost frames on a loaded machine). A missing answer is a failure after
S seconds (default 30), reported with the tick, never a silent shortfall.

OUT_LOG: the firmware's frames in candump -L format (what hil_check.py --replay compares).
Uses only the standard library's AF_CAN sockets. Exit 0 when every answer came, 1 otherwise.
"""
import socket
import struct
import sys
import time

FRAME = struct.Struct("=IB3x8s")
STATUS_ID = 0x210


def ticks_of(log):
    """[(host frames [(id, data)], expected BMS_Status count)] in recorded order."""
    groups, host, statuses, answered = [], [], 0, False
    for line in open(log):
        if not line.startswith("("):
            continue
        can_id, hexdata = line.split()[2].split("#")
        can_id, data = int(can_id, 16), bytes.fromhex(hexdata)
        if can_id < 0x200:
            if answered:  # the first host frame after an answer opens the next tick
                groups.append((host, statuses))
                host, statuses, answered = [], 0, False
            host.append((can_id, data))
        else:
            answered = True
            statuses += can_id == STATUS_ID
    if host or statuses:
        groups.append((host, statuses))
    return groups


def main():
    args = sys.argv[1:]
    timeout_s = 30.0
    if "--timeout-s" in args:
        i = args.index("--timeout-s")
        timeout_s = float(args[i + 1])
        del args[i:i + 2]
    if len(args) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    iface, log, out = args
    groups = ticks_of(log)
    s = socket.socket(socket.AF_CAN, socket.SOCK_RAW, socket.CAN_RAW)
    s.setsockopt(socket.SOL_CAN_RAW, socket.CAN_RAW_FILTER, struct.pack("=II", 0x200, 0x700))
    s.bind((iface,))
    sent = answers = 0
    t0 = time.monotonic()
    with open(out, "w") as rec:
        for k, (host, expected) in enumerate(groups):
            for can_id, data in host:
                s.send(FRAME.pack(can_id, len(data), data.ljust(8, b"\0")))
                sent += 1
            got = 0
            deadline = time.monotonic() + timeout_s
            while got < expected:
                s.settimeout(max(0.001, deadline - time.monotonic()))
                try:
                    raw = s.recv(FRAME.size)
                except socket.timeout:
                    print(f"hil_replay: tick {k}: {got} of {expected} BMS_Status answers within {timeout_s} s "
                          f"({answers} answers so far)", file=sys.stderr)
                    return 1
                can_id, dlc, data = FRAME.unpack(raw)
                can_id &= socket.CAN_SFF_MASK
                rec.write(f"({time.time():.6f}) {iface} {can_id:03X}#{data[:dlc].hex().upper()}\n")
                answers += 1
                got += can_id == STATUS_ID
    wall = time.monotonic() - t0
    print(f"hil_replay: ticks={len(groups)} frames_replayed={sent} answers_recorded={answers} wall_s={wall:.1f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
