#!/usr/bin/python3
"""A cycler record on the Cortex-M4F: the float firmware under QEMU over the measurement stream
`bmssim estimate` ticked on, against the host's double build of the same source, charge by charge.

  record_replay.py --bmssim EXE --host-exe EXE --image ELF --cell CELL.bpx.json --data FILE|DIR...
                   --out DIR [--qemu EXE] [--machine M] [--learning] [--limit-pct 0.5]
                   [--estimate-limit-pct 1e-6]
  record_replay.py --host-only ... (no --image: steps 1 and 2 on the host, the first check only)

1. `bmssim estimate --data ... --cell CELL --no-learning --write-firmware-stream` (the readers,
   the gaps, the power cycles and the model tick are the host's own code): DIR/estimate/, with
   firmware_stream.bin (BMSMEAS3: per sample that reaches the tick its voltage, current,
   temperature and the ticks missed before it; the tick, the sample step, learning).
2. The host's double build (bms_record_replay_host) and the board image (bms_record_replay.elf
   under qemu-system-arm, -semihosting -icount shift=0, reading ./measured.bin) tick over it,
   each configured as estimate was (record_config: make_config + adapt_to_sample_step).
3. Checks, each failing the run:
   - the host double build equals estimate's estimates.csv at every tick (film, model voltage,
     capacity, mode) within --estimate-limit-pct: the reference is the firmware as `estimate`
     runs it, so the board is compared with what the host reports;
   - the board's CC charges (runs of the mode detector's cc_charge) are the host's: same count,
     same first and last tick;
   - per charge, board against host double, |b/d - 1| <= --limit-pct for: the film at the CC end,
     the capacity at the CC end, the model voltage at the CC start, the CC end and the charge's
     end (the last tick before the next discharge or CC charge: the CV and the rests included), and
     the charge counted on the measured charging current from the CC start to the charge's end
     (trapezoids on the ticks' times; it moves only with the charge's boundaries).
   Reported besides (not limited): every tick's relative differences (film, capacity, model
   voltage; median and max), the mode agreement, the board's instructions per tick (mean, worst).
Writes DIR/summary.json. Exit 0 on pass, 1 on a failed check or run, 2 on bad input.
"""
import argparse
import csv
import json
import math
import os
import shutil
import statistics
import struct
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import m4f_blind  # noqa: E402  (read_run, qemu_cmd, run_timed)

MODES = {"rest": 0, "cc_discharge": 1, "cv_discharge": 2, "cc_charge": 3, "cv_charge": 4, "unknown": 15}
CC_CHARGE = 3
ENDS_CHARGE = (1, 2, 3)  # cc_discharge, cv_discharge, the next cc_charge
# Row layout of m4f_blind.read_run: tick, mode, active, r_film, gain, nu, z, capacity, model_v.
FILM, Z, CAP, MODEL_V = 3, 6, 7, 8


class BadInput(Exception):
    pass


def parse_args():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--bmssim", required=True)
    p.add_argument("--host-exe", required=True)
    p.add_argument("--image")
    p.add_argument("--host-only", action="store_true", help="no board: the host double build against estimate")
    p.add_argument("--cell", required=True)
    p.add_argument("--data", required=True, nargs="+")
    p.add_argument("--out", required=True)
    p.add_argument("--qemu", default="qemu-system-arm")
    p.add_argument("--machine", default="mps2-an386")
    p.add_argument("--learning", action="store_true", help="learning on (the record must allow it)")
    p.add_argument("--estimate-arg", action="append", default=[],
                   help="an option given to estimate that the replays are not told (a canary: the checks must fail)")
    p.add_argument("--limit-pct", type=float, default=0.5)
    p.add_argument("--estimate-limit-pct", type=float, default=1e-6)
    a = p.parse_args()
    if (a.image is None) != a.host_only:
        raise BadInput("give --image, or --host-only without it")
    for path, what in [(a.bmssim, "--bmssim"), (a.host_exe, "--host-exe"), (a.image, "--image"), (a.cell, "--cell")]:
        if path is not None and not os.path.isfile(path):
            raise BadInput(f"{what} {path}: no such file")
    for d in a.data:
        if not os.path.exists(d):
            raise BadInput(f"--data {d}: no such file or folder")
    if not (a.limit_pct > 0.0 and a.estimate_limit_pct >= 0.0):
        raise BadInput("--limit-pct must be > 0, --estimate-limit-pct >= 0")
    return a


def run_estimate(a, out):
    cmd = [a.bmssim, "estimate", "--cell", a.cell, "--write-firmware-stream", "--quiet", "--out", out]
    for d in a.data:
        cmd += ["--data", d]
    if not a.learning:
        cmd.append("--no-learning")
    cmd += a.estimate_arg
    t0 = time.monotonic()
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if r.returncode != 0:
        raise RuntimeError(f"bmssim estimate exited {r.returncode}: {r.stderr.strip()}")
    return time.monotonic() - t0, cmd


def read_stream(path):
    """(tick_s, sample_step_s, learning, [(t_s, current_a)]) of a BMSMEAS3 file."""
    with open(path, "rb") as f:
        head = f.read(40)
        if len(head) != 40 or head[:8] != b"BMSMEAS3":
            raise RuntimeError(f"{path}: not a BMSMEAS3 stream")
        count, zero = struct.unpack("<II", head[8:16])
        tick_s, step_s, learning = struct.unpack("<ddd", head[16:40])
        body = f.read()
    if len(body) != count * 32:
        raise RuntimeError(f"{path}: {len(body)} bytes of samples, expected {count} x 32")
    samples, t = [], 0.0
    for k, (_v, i, _temp, missed) in enumerate(struct.iter_unpack("<dddd", body)):
        t += (missed + 1.0) * tick_s if k else 0.0
        samples.append((t, i))
    return tick_s, step_s, learning, samples


def rel_pct(b, d):
    if math.isnan(b) or math.isnan(d):
        return 0.0 if math.isnan(b) and math.isnan(d) else math.inf
    if d == 0.0:
        return 0.0 if b == 0.0 else math.inf
    return abs(b - d) / abs(d) * 100.0


def spread(values):
    vals = [v for v in values if not math.isnan(v)]
    return {"median_pct": statistics.median(vals) if vals else None, "max_pct": max(vals) if vals else None}


def estimate_check(est_csv, dbl):
    """The host double replay against estimate's estimates.csv, tick by tick."""
    worst = {"r_film": 0.0, "model_v": 0.0, "capacity": 0.0}
    identical = {k: 0 for k in worst}
    mode_diff, rows = 0, 0
    with open(est_csv) as f:
        for row, d in zip(csv.DictReader(f), dbl):
            rows += 1
            for key, col, idx in [("r_film", "r_film_est_ohm_m2", FILM), ("model_v", "model_voltage_v", MODEL_V),
                                  ("capacity", "capacity_est_ah", CAP)]:
                text = row[col]
                e = float(text) if text not in ("", "nan", "NaN") else math.nan
                r = rel_pct(d[idx], e)
                identical[key] += r == 0.0
                worst[key] = max(worst[key], r)
            mode_diff += MODES.get(row["mode"], -1) != d[1]
    return {"ticks": rows, "max_rel_diff_pct": worst, "identical_ticks": identical, "mode_differs_ticks": mode_diff}


def charges(rows, samples):
    """The CC charges of a run (estimate's: runs of the detector's cc_charge): (first CC tick, last
    CC tick, last tick of the charge: before the next discharge or CC charge, the CV and rests
    between them included)."""
    out, k, n = [], 0, len(rows)
    while k < n:
        if rows[k][1] != CC_CHARGE:
            k += 1
            continue
        start = k
        while k + 1 < n and rows[k + 1][1] == CC_CHARGE:
            k += 1
        cc_end = k
        while k + 1 < n and rows[k + 1][1] not in ENDS_CHARGE:
            k += 1
        out.append((start, cc_end, k))
        k += 1
    return out


def counted_ah(samples, start, end):
    q = 0.0
    for k in range(start + 1, end + 1):
        (t0, i0), (t1, i1) = samples[k - 1], samples[k]
        q += -0.5 * (min(i0, 0.0) + min(i1, 0.0)) * (t1 - t0)  # charging current only
    return q / 3600.0


def charge_values(rows, samples, ch):
    start, cc_end, end = ch
    return {"r_film_cc_end": rows[cc_end][FILM], "capacity_cc_end": rows[cc_end][CAP],
            "model_v_cc_start": rows[start][MODEL_V], "model_v_cc_end": rows[cc_end][MODEL_V],
            "model_v_charge_end": rows[end][MODEL_V], "counted_ah": counted_ah(samples, start, end)}


def compare_charges(m4f, dbl, samples):
    cb, cd = charges(m4f, samples), charges(dbl, samples)
    boundary_diffs = sum(1 for b, d in zip(cb, cd) if b != d) + abs(len(cb) - len(cd))
    per_charge, diffs = [], {}
    for idx, (b, d) in enumerate(zip(cb, cd)):
        vb, vd = charge_values(m4f, samples, b), charge_values(dbl, samples, d)
        entry = {"index": idx + 1, "cc_start_tick": d[0], "cc_end_tick": d[1], "charge_end_tick": d[2]}
        for key in vd:
            r = rel_pct(vb[key], vd[key])
            diffs.setdefault(key, []).append(r)
            entry[key] = {"board": vb[key], "host_double": vd[key], "rel_diff_pct": r}
        per_charge.append(entry)
    stats = {key: spread(v) for key, v in diffs.items()}
    return {"charges_host": len(cd), "charges_board": len(cb), "boundary_differences": boundary_diffs,
            "per_quantity": stats, "per_charge": per_charge}


def tick_diffs(m4f, dbl):
    out = {}
    for key, idx in [("r_film", FILM), ("capacity", CAP), ("model_v", MODEL_V)]:
        out[key] = spread([rel_pct(b[idx], d[idx]) for b, d in zip(m4f, dbl)])
    z = [abs(b[Z] - d[Z]) * 1e3 for b, d in zip(m4f, dbl)]
    out["z_abs_diff_mv"] = {"median": statistics.median(z) if z else None, "max": max(z) if z else None}
    out["mode_agree_ticks"] = sum(1 for b, d in zip(m4f, dbl) if b[1] == d[1])
    return out


def run_replays(a, d):
    runs, times = {}, {}
    todo = [("host_double", [os.path.abspath(a.host_exe), "measured.bin"])]
    if not a.host_only:
        todo.append(("m4f", m4f_blind.qemu_cmd(a)))
    for name, cmd in todo:
        out = os.path.join(d, f"{name}.txt")
        rc, times[name] = m4f_blind.run_timed(cmd, out, cwd=d)
        if rc != 0:
            raise RuntimeError(f"{name} run exited {rc} ({' '.join(cmd)} in {d}; output {out})")
        runs[name] = m4f_blind.read_run(out)
    return runs, times


def check_runs(runs, count):
    (m4f, sm), (dbl, sd) = runs["m4f"], runs["host_double"]
    for key, want in [("format", ("BMSMEAS3", "BMSMEAS3")), ("scalar", ("float", "double"))]:
        if (sm.get(key), sd.get(key)) != want:
            raise RuntimeError(f"{key}: board {sm.get(key)}, host {sd.get(key)} (expected {want})")
    for key in ("source_hash", "cell", "record"):
        if sm.get(key) != sd.get(key):
            raise RuntimeError(f"{key}: board '{sm.get(key)}', host '{sd.get(key)}': rebuild both from the same sources")
    if len(m4f) != count or len(dbl) != count:
        raise RuntimeError(f"ticks: board {len(m4f)}, host {len(dbl)}, stream {count}")


def verdicts(a, s):
    fails = []
    e = s["host_double_vs_estimate"]
    worst = max(e["max_rel_diff_pct"].values())
    if worst > a.estimate_limit_pct or e["mode_differs_ticks"] or e["ticks"] != s["ticks"]:
        fails.append(f"host double vs bmssim estimate: max {worst:.3g} % (limit {a.estimate_limit_pct:g} %), "
                     f"{e['mode_differs_ticks']} ticks of another mode, {e['ticks']} of {s['ticks']} ticks compared")
    c = s["charges"]
    if c["boundary_differences"] or c["charges_host"] == 0:
        fails.append(f"charges: board {c['charges_board']}, host {c['charges_host']}, "
                     f"{c['boundary_differences']} with other boundaries")
    over = {k: v["max_pct"] for k, v in c["per_quantity"].items() if v["max_pct"] is not None and v["max_pct"] > a.limit_pct}
    if over:
        fails.append("board vs host double, per charge: " +
                     ", ".join(f"{k} max {v:.3g} %" for k, v in over.items()) + f" (limit {a.limit_pct:g} %)")
    return fails


def host_only(a, d, runs, count, est_dir):
    dbl, sd = runs["host_double"]
    e = estimate_check(os.path.join(est_dir, "estimates.csv"), dbl)
    worst = max(e["max_rel_diff_pct"].values())
    ok = sd.get("format") == "BMSMEAS3" and len(dbl) == count and e["ticks"] == count and \
        worst <= a.estimate_limit_pct and e["mode_differs_ticks"] == 0
    with open(os.path.join(d, "summary.json"), "w") as f:
        json.dump({"ticks": count, "host_double_vs_estimate": e, "pass": ok}, f, indent=1)
    print(f"host double vs estimate: {count} ticks, max {e['max_rel_diff_pct']} %, identical {e['identical_ticks']}, "
          f"{e['mode_differs_ticks']} ticks of another mode")
    print("PASS: the host double build equals bmssim estimate" if ok else
          f"FAIL: host double vs bmssim estimate: max {worst:.3g} % (limit {a.estimate_limit_pct:g} %)")
    return 0 if ok else 1


def main():
    try:
        a = parse_args()
    except BadInput as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    d = os.path.abspath(a.out)
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d)
    try:
        est_dir = os.path.join(d, "estimate")
        est_wall, est_cmd = run_estimate(a, est_dir)
        stream = os.path.join(est_dir, "firmware_stream.bin")
        tick_s, step_s, learning, samples = read_stream(stream)
        os.symlink(stream, os.path.join(d, "measured.bin"))
        runs, times = run_replays(a, d)
        if a.host_only:
            return host_only(a, d, runs, len(samples), est_dir)
        check_runs(runs, len(samples))
    except RuntimeError as e:
        print(f"FAIL: {e}")
        return 1
    (m4f, sm), (dbl, _sd) = runs["m4f"], runs["host_double"]
    s = {"data": a.data, "cell": a.cell, "estimate_command": est_cmd, "ticks": len(samples), "tick_s": tick_s,
         "sample_step_s": step_s, "learning": bool(learning), "limit_pct": a.limit_pct,
         "host_double_vs_estimate": estimate_check(os.path.join(est_dir, "estimates.csv"), dbl),
         "charges": compare_charges(m4f, dbl, samples), "ticks_diff": tick_diffs(m4f, dbl),
         "board": {k: sm.get(k) for k in ("worst_tick_instructions", "mean_tick_instructions", "status_or",
                                          "newton_cap_hits", "firmware_state_bytes", "resyncs")},
         "wall_s": {"estimate": est_wall, **times}}
    fails = verdicts(a, s)
    s["pass"] = not fails
    with open(os.path.join(d, "summary.json"), "w") as f:
        json.dump(s, f, indent=1)
    c, t = s["charges"], s["ticks_diff"]
    print(f"record: {len(samples)} ticks (model tick {tick_s} s, samples every {step_s} s), {c['charges_host']} CC charges; "
          f"board {times['m4f']:.1f} s, host double {times['host_double']:.1f} s, estimate {est_wall:.1f} s")
    print(f"board: mean {sm.get('mean_tick_instructions')} instructions per tick, worst {sm.get('worst_tick_instructions')}")
    for key, v in c["per_quantity"].items():
        print(f"per charge {key}: median {v['median_pct']:.3g} %, max {v['max_pct']:.3g} %")
    for key in ("r_film", "capacity", "model_v"):
        print(f"per tick {key}: median {t[key]['median_pct']:.3g} %, max {t[key]['max_pct']:.3g} %")
    e = s["host_double_vs_estimate"]
    print(f"host double vs estimate: max {e['max_rel_diff_pct']} %, identical ticks {e['identical_ticks']} of {e['ticks']}")
    for msg in fails:
        print(f"FAIL: {msg}")
    if not fails:
        print(f"PASS: {c['charges_host']} charges, board within {a.limit_pct:g} % of the host double build")
    return 0 if not fails else 1


if __name__ == "__main__":
    sys.exit(main())
