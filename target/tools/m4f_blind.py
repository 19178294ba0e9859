#!/usr/bin/python3
"""Blind identification on the Cortex-M4F: the float firmware (best profile) under QEMU over
the blind truths' measured columns, against the host's double build of the same source.

Truths: drawn as float_blind.py draws them (blind.md set 1; the same seeds give the same
truths), simulated with bmssim; --temperature-k, --effect and --noise-t-k make them
temperature-varying (e.g. --temperature-k 288.15 --effect thermal=0.05: a 15 C ambient and
self-heating). Per truth: the measured voltage, current and temperature (the truth.csv's
voltage_meas_v, current_meas_a and temperature_meas_k, only those: the information rule; never
the truth's temperature_k) are written to DIR/truthK/measured.bin (BMSMEAS2; BMSMEAS1 without the
temperature with --no-temperature or when the truth.csv has no temperature_meas_k); the host's
double build (bms_m4f_blind_host) and the board image (bms_m4f_blind.elf, under qemu-system-arm
with semihosting and -icount shift=0, reading the file in chunks) run the same tick over it;
float_check.py scores both against the truth.

  m4f_blind.py --bmssim EXE --host-exe EXE --image ELF --out DIR [--qemu EXE] [--machine M]
               [--host-float-exe EXE] [--truths 10] [--cycles 5] [--seed 1] [--max-ticks N]
               [--noise-v-mv 0.2] [--noise-t-k 0] [--temperature-k K] [--effect NAME=VALUE]...
               [--no-temperature] [--limit-pct 0.5] [--tick-limit 300000] [--estimate-check] [--keep]

The 0.5 % (--limit-pct), per truth, M4F against the host's double build:
  - film estimate: relative difference |f/d - 1|, median over the CC-charge ticks and at the
    end of every CC charge, each <= 0.5 %;
  - accuracy: film error against the truth (median over each CC charge, per cycle) and
    growth_err_pct, each within 0.5 percentage points of double's;
  - capacity (the tick's open-circuit capacity of the identified inventory, once reported):
    relative difference |c/d - 1| at every tick where double reports one, max <= 0.5 %.
The board's costliest tick (instructions, QEMU -icount shift=0) must stay within --tick-limit.
--estimate-check: also runs `bmssim estimate` on the same truth.csv and reports how far the host
double replay's film and capacity are from its estimates.csv (the reference is the firmware as
the host estimator runs it).
Writes DIR/summary.json. Exit 0 when every truth passes, 1 when one fails or a run fails,
2 on bad input (before any long work).
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
import float_blind  # noqa: E402  (the truths' draw)
import float_check  # noqa: E402  (relative differences)

CC_CHARGE = 3
MAGIC_VI = b"BMSMEAS1"    # voltage, current
MAGIC_VIT = b"BMSMEAS2"   # voltage, current, measured temperature


class BadInput(Exception):
    pass


def convert_truth(truth_csv, out_dir, max_ticks, use_temperature=True):
    """measured.bin (voltage, current and, when the truth.csv has it and use_temperature, the
    sensor's temperature_meas_k) and score_truth.csv (cycle, r_film, capacity) from a truth.csv.
    Returns (ticks, format)."""
    with open(truth_csv) as f:
        head = f.readline().strip().split(",")
        need = ["t_s", "cycle", "voltage_meas_v", "current_meas_a", "r_film_ohm_m2"]
        for name in need:
            if name not in head:
                raise BadInput(f"{truth_csv}: line 1: no {name} column")
        with_t = use_temperature and "temperature_meas_k" in head
        if with_t:
            need.append("temperature_meas_k")  # the sensor; never the truth's temperature_k
        idx = [head.index(n) for n in need]
        icap = head.index("capacity_ah") if "capacity_ah" in head else None
        samples, score = [], ["cycle,r_film_ohm_m2,capacity_ah\n"]
        for n, line in enumerate(f, start=2):
            if max_ticks and len(samples) == max_ticks:
                break
            p = line.rstrip("\n").split(",")
            try:
                vals = [float(p[i]) for i in idx]
                score.append(f"{int(p[idx[1]])},{p[idx[4]]},{p[icap] if icap is not None else 'nan'}\n")
            except (ValueError, IndexError):
                raise BadInput(f"{truth_csv}: line {n}: {', '.join(need)} not a number")
            if with_t and not vals[5] > 0.0:
                raise BadInput(f"{truth_csv}: line {n}: temperature_meas_k must be a positive temperature in K")
            samples.append(tuple(vals[2:4] + vals[5:]))
    if not samples:
        raise BadInput(f"{truth_csv}: no samples")
    fmt = "<ddd" if with_t else "<dd"
    with open(os.path.join(out_dir, "measured.bin"), "wb") as f:
        f.write((MAGIC_VIT if with_t else MAGIC_VI) + struct.pack("<II", len(samples), 0))
        f.write(b"".join(struct.pack(fmt, *v) for v in samples))
    with open(os.path.join(out_dir, "score_truth.csv"), "w") as f:
        f.writelines(score)
    return len(samples), (MAGIC_VIT if with_t else MAGIC_VI).decode()


def read_run(path):
    """Rows (tick, mode, active, r_film, gain, nu, z, capacity) with the values decoded, and the
    summary."""
    rows, summary = [], {}
    with open(path) as f:
        for line in f:
            if line.startswith("#"):
                parts = line[1:].split(None, 1)
                summary[parts[0]] = parts[1].strip() if len(parts) > 1 else ""
                continue
            p = line.split()
            vals = [struct.unpack(">f" if len(h) == 8 else ">d", bytes.fromhex(h))[0] for h in p[3:]]
            rows.append([int(p[0]), int(p[1]), int(p[2])] + vals)
    return rows, summary


def write_merged(path, m4f, dbl):
    with open(path, "w") as f:
        f.write("# columns tick mode_f mode_d active_f active_d r_film_f r_film_d gain_f gain_d nu_f nu_d z_f z_d\n")
        for a, b in zip(m4f, dbl):
            f.write(f"{a[0]} {a[1]} {b[1]} {a[2]} {b[2]} {a[3]!r} {b[3]!r} {a[4]!r} {b[4]!r} "
                    f"{a[5]!r} {b[5]!r} {a[6]!r} {b[6]!r}\n")


def charge_ends(m4f, dbl, truth_film, cycles):
    """Film and gain at the end of every CC charge (the double build's mode selects them)."""
    ends = []
    for k, b in enumerate(dbl):
        if b[1] == CC_CHARGE and (k + 1 == len(dbl) or dbl[k + 1][1] != CC_CHARGE):
            f, d, t = m4f[k][3], b[3], truth_film[k]
            ends.append({"tick": k, "cycle": cycles[k], "film_m4f": f, "film_double": d, "film_truth": t,
                         "film_rel_diff_pct": float_check.rel_pct(f, d), "film_err_m4f_pct": abs(f / t - 1) * 100,
                         "film_err_double_pct": abs(d / t - 1) * 100, "gain_m4f": m4f[k][4], "gain_double": b[4]})
    return ends


def capacity_diff(m4f, dbl, truth_cap):
    """Capacity M4F vs double at every tick where double reports one (not NaN), and at the end
    against the truth's capacity_ah."""
    rel, one_sided = [], 0
    for a, b in zip(m4f, dbl):
        if math.isnan(b[7]):
            one_sided += 0 if math.isnan(a[7]) else 1
            continue
        if math.isnan(a[7]):
            one_sided += 1
            continue
        rel.append(float_check.rel_pct(a[7], b[7]))
    if not rel:
        return None
    end_f, end_d, end_t = m4f[-1][7], dbl[-1][7], truth_cap[-1]
    return {"ticks_compared": len(rel), "ticks_reported_by_one_only": one_sided, "max_pct": max(rel),
            "median_pct": statistics.median(rel), "end_m4f_ah": end_f, "end_double_ah": end_d, "end_truth_ah": end_t,
            "end_err_m4f_pct": abs(end_f / end_t - 1) * 100 if end_t == end_t else None,
            "end_err_double_pct": abs(end_d / end_t - 1) * 100 if end_t == end_t else None}


def run_timed(cmd, out_path, cwd=None):
    t0 = time.monotonic()
    with open(out_path, "w") as f:
        rc = subprocess.run(cmd, stdout=f, stderr=subprocess.PIPE, text=True, cwd=cwd).returncode
    return rc, time.monotonic() - t0


def qemu_cmd(a):
    # -icount shift=0: one instruction per ns of virtual time, so that SysTick counts the
    # tick's instructions (as the target_tick_cost test runs the replay image).
    return [a.qemu, "-M", a.machine, "-nographic", "-monitor", "none", "-serial", "none", "-semihosting",
            "-icount", "shift=0,sleep=off", "-kernel", os.path.abspath(a.image)]


def run_builds(a, d):
    """Host double (and float), then the board; returns the decoded runs and the QEMU time."""
    runs, times = {}, {}
    exes = [("double", [os.path.abspath(a.host_exe), "measured.bin"])]
    if a.host_float_exe:
        exes.append(("host_float", [os.path.abspath(a.host_float_exe), "measured.bin"]))
    exes.append(("m4f", qemu_cmd(a)))
    for name, cmd in exes:
        out = os.path.join(d, f"{name}.txt")
        rc, times[name] = run_timed(cmd, out, cwd=d)
        if rc != 0:
            raise RuntimeError(f"{name} run exited {rc} ({' '.join(cmd)} in {d}; output {out})")
        runs[name] = read_run(out)
    return runs, times


def check_runs(runs, ticks, fmt):
    (m4f, sm), (dbl, sd) = runs["m4f"], runs["double"]
    if sm.get("format") != fmt or sd.get("format") != fmt:
        raise RuntimeError(f"input format: board {sm.get('format')}, host {sd.get('format')}, written {fmt}")
    if sm.get("scalar") != "float" or sd.get("scalar") != "double":
        raise RuntimeError(f"scalars: board {sm.get('scalar')}, host {sd.get('scalar')} (expected float, double)")
    if sm.get("source_hash") != sd.get("source_hash"):
        raise RuntimeError(f"firmware source hash: board {sm.get('source_hash')}, host {sd.get('source_hash')}: "
                           "rebuild both from the same sources")
    if len(m4f) != ticks or len(dbl) != ticks:
        raise RuntimeError(f"ticks: board {len(m4f)}, host {len(dbl)}, input {ticks}")


def bit_identical(a_rows, b_rows):
    return sum(1 for a, b in zip(a_rows, b_rows) if a == b)


def score_truth(a, d, runs, ticks):
    m4f, dbl = runs["m4f"][0], runs["double"][0]
    merged = os.path.join(d, "merged.txt")
    write_merged(merged, m4f, dbl)
    truth = os.path.join(d, "score_truth.csv")
    score = os.path.join(d, "float_check.json")
    p = subprocess.run([sys.executable, os.path.join(HERE, "float_check.py"), "--run", merged, "--truth", truth,
                        "--json", score, "--limit-pct", str(a.limit_pct)], stdout=subprocess.PIPE, text=True)
    if not os.path.exists(score):
        raise RuntimeError(f"float_check.py failed on {merged}: {p.stdout}")
    with open(score) as f:
        res = json.load(f)
    with open(truth) as f:
        f.readline()
        rows = [line.split(",") for line in f]
    cycles, film, cap = [int(r[0]) for r in rows], [float(r[1]) for r in rows], [float(r[2]) for r in rows]
    res["charge_ends"] = charge_ends(m4f, dbl, film, cycles)
    for e in res["charge_ends"]:
        if e["film_rel_diff_pct"] > a.limit_pct:
            res["failures"].append(f"charge end tick {e['tick']}: film M4F vs double {e['film_rel_diff_pct']:.4f} %")
    res["capacity"] = capacity_diff(m4f, dbl, cap)
    c = res["capacity"]
    if c is not None and (c["max_pct"] > a.limit_pct or c["ticks_reported_by_one_only"]):
        res["failures"].append(f"capacity M4F vs double: max {c['max_pct']:.4f} % over {c['ticks_compared']} ticks, "
                               f"{c['ticks_reported_by_one_only']} ticks reported by one build only")
    worst = int(runs["m4f"][1].get("worst_tick_instructions", "0").split()[0])
    res["worst_tick_instructions"] = worst
    res["worst_tick"] = runs["m4f"][1].get("worst_tick_instructions", "")
    if worst == 0 or worst > a.tick_limit:
        res["failures"].append(f"board's costliest tick {worst} instructions (limit {a.tick_limit}; 0: not counted, "
                               "QEMU without -icount?)")
    if "host_float" in runs:
        res["m4f_vs_host_float_identical_ticks"] = bit_identical(m4f, runs["host_float"][0])
    res["m4f_summary"], res["double_summary"] = runs["m4f"][1], runs["double"][1]
    os.remove(merged)
    return res


def temperature_range(truth_csv, ticks):
    """The sensor's temperature over the replayed ticks (min, max), for the record."""
    with open(truth_csv) as f:
        r = csv.reader(f)
        head = next(r)
        if "temperature_meas_k" not in head:
            return None
        i = head.index("temperature_meas_k")
        vals = [float(row[i]) for _, row in zip(range(ticks), r)]
    return {"min": min(vals), "max": max(vals)}


def estimate_check(a, d, dbl):
    """`bmssim estimate` (defaults: the best profile, reduced model) on the same truth.csv against
    the host double replay, tick by tick over the replayed ticks."""
    out = os.path.join(d, "estimate")
    shutil.rmtree(out, ignore_errors=True)
    subprocess.run([a.bmssim, "estimate", "--data", os.path.join(d, "truth.csv"), "--out", out], check=True,
                   stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    film_same = cap_same = 0
    film_rel = cap_rel = 0.0
    with open(os.path.join(out, "estimates.csv")) as f:
        for row, b in zip(csv.DictReader(f), dbl):
            ef, ec = float(row["r_film_est_ohm_m2"]), float(row["capacity_est_ah"])
            film_same += ef == b[3]
            film_rel = max(film_rel, float_check.rel_pct(b[3], ef))
            if math.isnan(b[7]):
                continue
            cap_same += ec == b[7]
            cap_rel = max(cap_rel, float_check.rel_pct(b[7], ec))
    shutil.rmtree(out, ignore_errors=True)
    return {"film_identical_ticks": film_same, "film_max_rel_diff_pct": film_rel,
            "capacity_identical_ticks": cap_same, "capacity_max_rel_diff_pct": cap_rel, "ticks": len(dbl)}


def one_truth(a, k, params):
    d = os.path.join(a.out, f"truth{k}")
    # This script's own folder of an earlier run (bmssim's --out refuses a folder holding the
    # converted streams and run outputs written beside truth.csv).
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d, exist_ok=True)
    cmd = [a.bmssim, "simulate", "--cycles", str(a.cycles), "--noise-v-mv", str(a.noise_v_mv),
           "--seed", str(a.seed + k), "--quiet", "--out", d]
    if a.noise_t_k:
        cmd += ["--noise-t-k", str(a.noise_t_k)]
    for name, value in params.items():
        cmd += ["--set", f"{name}={value:.6g}"]
    if a.temperature_k is not None:
        cmd += ["--set", f"temperature_k={a.temperature_k}"]
    for e in a.effect:
        cmd += ["--effect", e]
    t0 = time.monotonic()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    ticks, fmt = convert_truth(os.path.join(d, "truth.csv"), d, a.max_ticks, not a.no_temperature)
    sim_s = time.monotonic() - t0
    runs, times = run_builds(a, d)
    check_runs(runs, ticks, fmt)
    res = score_truth(a, d, runs, ticks)
    res.update({"truth": k, "set": params, "command": " ".join(cmd), "ticks": ticks, "format": fmt,
                "simulate_s": sim_s, "run_s": times, "qemu_ms_per_1000_ticks": times["m4f"] / ticks * 1e6,
                "temperature_meas_k": temperature_range(os.path.join(d, "truth.csv"), ticks)})
    if a.estimate_check:
        res["vs_estimate"] = e = estimate_check(a, d, runs["double"][0])
        if e["film_identical_ticks"] != e["ticks"]:
            res["failures"].append(f"host double vs bmssim estimate: film identical in {e['film_identical_ticks']} "
                                   f"of {e['ticks']} ticks (max {e['film_max_rel_diff_pct']:.3g} %)")
    for name in ("truth.csv", "measured.bin", "m4f.txt", "double.txt", "host_float.txt"):
        if not a.keep and os.path.exists(os.path.join(d, name)):
            os.remove(os.path.join(d, name))  # tens of MB per truth; the scores are kept
    return res


def worst_cycle(errs, skip):
    vals = [v for c, v in errs.items() if int(c) > skip]
    return max(vals) if vals else max(errs.values())


def print_truth(res):
    f, dd = res["float"], res["double"]
    ends = res["charge_ends"]
    gf = "-" if f["growth_err_pct"] is None else f"{f['growth_err_pct']:.2f}"
    gd = "-" if dd["growth_err_pct"] is None else f"{dd['growth_err_pct']:.2f}"
    print(f"{res['truth']:5d}  {res['film_float_vs_double_pct']['median']:.4f}  "
          f"{max(e['film_rel_diff_pct'] for e in ends) if ends else float('nan'):.4f}  "
          f"{worst_cycle(f['film_err_median_pct'], 2):.3f} / {worst_cycle(dd['film_err_median_pct'], 2):.3f}  "
          f"{gf} / {gd}  {f['gain_end']:.4f} / {dd['gain_end']:.4f}  qemu {res['run_s']['m4f']:.1f} s"
          + ("  FAIL" if res["failures"] else ""), flush=True)
    c, t = res["capacity"], res["temperature_meas_k"]
    print(f"       {res['format']}" + (f", temperature_meas_k {t['min']:.2f}-{t['max']:.2f} K" if t else "")
          + (f"; capacity M4F vs double max {c['max_pct']:.4f} % over {c['ticks_compared']} ticks, end "
             f"{c['end_m4f_ah']:.5f} / {c['end_double_ah']:.5f} Ah (truth {c['end_truth_ah']:.5f})" if c else "")
          + f"; costliest tick {res['worst_tick']}", flush=True)
    if "vs_estimate" in res:
        e = res["vs_estimate"]
        print(f"       host double vs bmssim estimate: film identical in {e['film_identical_ticks']} of {e['ticks']} "
              f"ticks (max {e['film_max_rel_diff_pct']:.3g} %), capacity identical in {e['capacity_identical_ticks']} "
              f"(max {e['capacity_max_rel_diff_pct']:.3g} %)", flush=True)
    for m in res["failures"]:
        print(f"       FAIL: {m}", flush=True)


def parse_args():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bmssim", required=True, help="host bmssim (simulates the truths)")
    ap.add_argument("--host-exe", required=True, help="bms_m4f_blind_host (the double reference)")
    ap.add_argument("--host-float-exe", help="bms_m4f_blind_host_float (optional: M4F vs host float)")
    ap.add_argument("--image", required=True, help="bms_m4f_blind.elf of the cortex-m4f preset")
    ap.add_argument("--qemu", default="qemu-system-arm")
    ap.add_argument("--machine", default="mps2-an386")
    ap.add_argument("--out", required=True)
    ap.add_argument("--truths", type=int, default=10)
    ap.add_argument("--cycles", type=int, default=5)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--max-ticks", type=int, default=0, help="only the first N ticks of each truth (0: all)")
    ap.add_argument("--noise-v-mv", type=float, default=0.2)
    ap.add_argument("--noise-t-k", type=float, default=0.0, help="temperature sensor noise (K, simulate's)")
    ap.add_argument("--temperature-k", type=float, help="the truth's ambient temperature (simulate --set temperature_k)")
    ap.add_argument("--effect", action="append", default=[], metavar="NAME=VALUE",
                    help="simulate --effect for every truth (repeatable), e.g. thermal=0.05")
    ap.add_argument("--no-temperature", action="store_true",
                    help="write BMSMEAS1 (voltage and current only): the firmware at its reference temperature")
    ap.add_argument("--limit-pct", type=float, default=0.5)
    ap.add_argument("--tick-limit", type=int, default=300000, help="the board's costliest tick (instructions)")
    ap.add_argument("--estimate-check", action="store_true",
                    help="compare the host double replay with `bmssim estimate` of the same truth (fails unless "
                         "the film is identical at every tick)")
    ap.add_argument("--keep", action="store_true", help="keep truth.csv, measured.bin and the runs' outputs")
    return ap.parse_args()


def validate(a):
    for name in ("bmssim", "host_exe", "host_float_exe", "qemu"):
        exe = getattr(a, name)
        if exe and not os.access(exe, os.X_OK) and not (os.sep not in exe and shutil.which(exe)):
            raise BadInput(f"--{name.replace('_', '-')} {exe}: not an executable")
    if not os.path.isfile(a.image):
        raise BadInput(f"--image {a.image}: no such file")
    if a.truths < 1 or a.cycles < 1 or a.max_ticks < 0 or a.limit_pct <= 0 or a.noise_v_mv < 0 or a.noise_t_k < 0:
        raise BadInput("--truths and --cycles must be >= 1, --max-ticks >= 0, --limit-pct > 0, --noise-v-mv and "
                       "--noise-t-k >= 0")
    if a.temperature_k is not None and not 200.0 < a.temperature_k < 400.0:
        raise BadInput(f"--temperature-k {a.temperature_k}: a temperature in K, e.g. 288.15")
    if a.tick_limit < 1:
        raise BadInput("--tick-limit must be >= 1")
    for e in a.effect:
        name, sep, value = e.partition("=")
        try:
            float(value)
        except ValueError:
            sep = ""
        if not sep or not name:
            raise BadInput(f"--effect {e}: NAME=VALUE with a number, e.g. thermal=0.05")


def main():
    a = parse_args()
    try:
        validate(a)
    except BadInput as e:
        print(f"m4f_blind: {e}", file=sys.stderr)
        return 2
    os.makedirs(a.out, exist_ok=True)
    rng = float_blind.random.Random(a.seed)
    cases, t_start = [], time.monotonic()
    print("truth  film M4F-vs-double median %  at charge ends max %  film err % (worst of cycles 3+) M4F/double  "
          "growth_err_pct M4F/double  gain M4F/double", flush=True)
    for k in range(a.truths):
        params = float_blind.draw(rng)
        try:
            res = one_truth(a, k, params)
        except BadInput as e:
            print(f"m4f_blind: {e}", file=sys.stderr)
            return 2
        except (RuntimeError, subprocess.CalledProcessError) as e:
            print(f"m4f_blind: truth {k}: {e}; check that the host and cortex-m4f builds are current", file=sys.stderr)
            return 1
        print_truth(res)
        cases.append(res)
    summary = {"truths": a.truths, "cycles": a.cycles, "max_ticks": a.max_ticks, "seed": a.seed,
               "noise_v_mv": a.noise_v_mv, "noise_t_k": a.noise_t_k, "temperature_k": a.temperature_k,
               "effects": a.effect, "no_temperature": a.no_temperature, "limit_pct": a.limit_pct,
               "tick_limit": a.tick_limit, "machine": a.machine,
               "wall_s": time.monotonic() - t_start, "qemu_s": sum(c["run_s"]["m4f"] for c in cases),
               "failed": sum(1 for c in cases if c["failures"]), "cases": cases}
    with open(os.path.join(a.out, "summary.json"), "w") as f:
        json.dump(summary, f, indent=1)
    print(f"{a.truths} truths, {summary['failed']} failed; QEMU {summary['qemu_s']:.0f} s, wall "
          f"{summary['wall_s']:.0f} s; {os.path.join(a.out, 'summary.json')}")
    return 1 if summary["failed"] else 0


if __name__ == "__main__":
    sys.exit(main())
