#!/usr/bin/python3
"""Checks a host-in-the-loop run with clients nobody in this project wrote.

usage: hil_check.py DBC HIL_DIR OFFLINE_DIR [SECOND_HIL_DIR] [--replay REPLAY_DIR] [--frames-check BIN]

1. python3-can reads HIL_DIR/can.log (candump format); python3-canmatrix decodes every
   BMS_Estimate1 / BMS_Health frame with the DBC; the decoded values must equal
   HIL_DIR/estimates.csv row by row (film resistance, mode, RCSI flag, residual).
2. The offline estimate (OFFLINE_DIR/estimates.csv, `bmssim estimate` on HIL_DIR/truth.csv)
   must give the same film resistance on the bus's 1e-10 ohm m2 grid in every tick
   (bit for bit at the bus resolution).
   With --frames-check (tests/cli/hil_frames_check.cpp, the firmware's own codec): the
   offline rows encoded as the firmware encodes its answers must equal the firmware's
   BMS_Estimate1/2/3 and BMS_Health frames byte for byte in every tick (0 mismatches): bit
   for bit where the firmware's answer is exact. The run's estimates.csv holds the decoded
   frames, so its doubles differ from the offline ones by the bus grid (printed, not a check).
3. With SECOND_HIL_DIR: the two lock-step logs must be byte-identical (determinism).
4. With --replay (tests/cli/hil_replay.sh: HIL_DIR/can.log's host frames replayed into a
   fresh firmware, each tick's only after the firmware answered the previous one): the firmware's frames of the replay
   must equal the original run's frame for frame, identifier and all 8 data bytes (so the
   estimates, theta, residual, status and alive counters are bit-identical on the bus).
Prints one line per check; exit 0 when all pass, 1 otherwise.
"""
import csv
import decimal
import subprocess
import sys

import can
import canmatrix
import canmatrix.formats


def to_raw(value, factor=decimal.Decimal("1e-10")):
    # The firmware's encoder: round half away from zero on the signal's grid.
    d = decimal.Decimal(repr(float(value))) / factor
    return int(d.to_integral_value(rounding=decimal.ROUND_HALF_UP))


def bms_frames(path):
    return [(m.arbitration_id, bytes(m.data)) for m in can.CanutilsLogReader(path)
            if 0x200 <= m.arbitration_id <= 0x2FF]


def main():
    args = sys.argv[1:]
    replay = None
    frames_check = None
    if "--frames-check" in args:
        i = args.index("--frames-check")
        frames_check = args[i + 1]
        del args[i:i + 2]
    if "--replay" in args:
        i = args.index("--replay")
        replay = args[i + 1]
        del args[i:i + 2]
    dbc, hil, offline = args[0:3]
    second = args[3] if len(args) > 3 else None
    db = canmatrix.formats.loadp_flat(dbc)
    est1 = db.frame_by_id(canmatrix.ArbitrationId(0x200))
    health = db.frame_by_id(canmatrix.ArbitrationId(0x203))
    decoded = []  # one dict per tick
    cur = {}
    for msg in can.CanutilsLogReader(hil + "/can.log"):
        if msg.arbitration_id == 0x200:
            v = est1.decode(bytes(msg.data))
            cur["r_raw"] = v["RFilm"].raw_value
            cur["mode"] = v["Mode"].raw_value
            cur["active"] = v["RcsiActive"].raw_value
        elif msg.arbitration_id == 0x203:
            v = health.decode(bytes(msg.data))
            cur["z_uv"] = v["ZResidual"].raw_value
        elif msg.arbitration_id == 0x210:  # BMS_Status closes the tick
            decoded.append(cur)
            cur = {}
    rows = list(csv.DictReader(open(hil + "/estimates.csv")))
    modes = {"rest": 0, "cc_discharge": 1, "cv_discharge": 2, "cc_charge": 3, "cv_charge": 4, "unknown": 15}
    ok = True
    bad = sum(1 for d, r in zip(decoded, rows)
              if d["r_raw"] != to_raw(r["r_film_est_ohm_m2"]) or d["mode"] != modes[r["mode"]]
              or d["active"] != int(r["rcsi_active"]) or d["z_uv"] != to_raw(r["z_v"], decimal.Decimal("1e-6")))
    good = len(decoded) == len(rows) and bad == 0
    ok &= good
    print(f"{'PASS' if good else 'FAIL'} python-can + canmatrix decode of can.log with the DBC: "
          f"{len(decoded)} ticks, {len(rows)} estimate rows, {bad} mismatches")
    off = list(csv.DictReader(open(offline + "/estimates.csv")))
    bad = sum(1 for a, b in zip(rows, off)
              if to_raw(a["r_film_est_ohm_m2"]) != to_raw(b["r_film_est_ohm_m2"]) or a["mode"] != b["mode"])
    good = len(off) == len(rows) and bad == 0
    ok &= good
    print(f"{'PASS' if good else 'FAIL'} lock-step estimates equal the offline `bmssim estimate` on the 1e-10 ohm m2 "
          f"bus grid: {len(rows)} ticks, {bad} mismatches")
    rel = max((abs(float(a["r_film_est_ohm_m2"]) - float(b["r_film_est_ohm_m2"])) / abs(float(b["r_film_est_ohm_m2"]))
               for a, b in zip(rows, off) if float(b["r_film_est_ohm_m2"]) != 0.0), default=0.0)
    print(f"INFO estimates.csv holds the decoded frames: largest relative film difference to the offline doubles "
          f"{rel:.2e} (the bus's 1e-10 ohm m2 grid)")
    if frames_check:
        r = subprocess.run([frames_check, hil + "/can.log", offline + "/estimates.csv"], capture_output=True, text=True)
        line = (r.stdout.strip() or r.stderr.strip() or "no output").splitlines()[-1]
        good = r.returncode == 0 and line.startswith("PASS") and " 0 mismatched ticks" in line
        ok &= good
        print(line if line.startswith(("PASS", "FAIL")) else f"FAIL {frames_check}: {line}")
    if second:
        same = open(hil + "/can.log", "rb").read() == open(second + "/can.log", "rb").read()
        ok &= same
        print(f"{'PASS' if same else 'FAIL'} two lock-step runs give byte-identical can.log")
    if replay:
        orig = bms_frames(hil + "/can.log")
        again = bms_frames(replay + "/replay_out.log")
        first_diff = next((i for i, (a, b) in enumerate(zip(orig, again)) if a != b), None)
        same = len(orig) == len(again) and first_diff is None
        ok &= same
        print(f"{'PASS' if same else 'FAIL'} acknowledgement-paced replay into a fresh firmware: {len(again)} of {len(orig)} "
              f"firmware frames recorded, first difference at frame {first_diff}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
