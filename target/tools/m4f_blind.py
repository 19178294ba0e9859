#!/usr/bin/python3
"""Blind identification on the Cortex-M4F: the float firmware (best profile) under QEMU over
the blind truths' measured columns, against the host's double build of the same source.

Truths: drawn as float_blind.py draws them (blind.md set 1; the same seeds give the same
truths), simulated with bmssim. Per truth: the measured voltage and current (only those: the
information rule) are written to DIR/truthK/measured.bin; the host's double build
(bms_m4f_blind_host) and the board image (bms_m4f_blind.elf, under qemu-system-arm with
semihosting, reading the file in chunks) run the same tick over it; float_check.py scores both
against the truth.

  m4f_blind.py --bmssim EXE --host-exe EXE --image ELF --out DIR [--qemu EXE] [--machine M]
               [--host-float-exe EXE] [--truths 10] [--cycles 5] [--seed 1] [--max-ticks N]
               [--noise-v-mv 0.2] [--limit-pct 0.5]

The 0.5 % (--limit-pct), per truth, M4F against the host's double build:
  - film estimate: relative difference |f/d - 1|, median over the CC-charge ticks and at the
    end of every CC charge, each <= 0.5 %;
  - accuracy: film error against the truth (median over each CC charge, per cycle) and
    growth_err_pct, each within 0.5 percentage points of double's.
Writes DIR/summary.json. Exit 0 when every truth passes, 1 when one fails or a run fails,
2 on bad input (before any long work).
"""
import argparse
import json
import os
import shutil
import struct
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import float_blind  # noqa: E402  (the truths' draw)

CC_CHARGE = 3
MAGIC = b"BMSMEAS1"


class BadInput(Exception):
    pass


def convert_truth(truth_csv, out_dir, max_ticks):
    """measured.bin (voltage, current) and score_truth.csv (cycle, r_film) from a truth.csv."""
    with open(truth_csv) as f:
        head = f.readline().strip().split(",")
        need = ("t_s", "cycle", "voltage_meas_v", "current_meas_a", "r_film_ohm_m2")
        for name in need:
            if name not in head:
                raise BadInput(f"{truth_csv}: line 1: no {name} column")
        it, ic, iv, ii, ir = (head.index(n) for n in need)
        samples, score = [], ["cycle,r_film_ohm_m2\n"]
        for n, line in enumerate(f, start=2):
            if max_ticks and len(samples) == max_ticks:
                break
            p = line.rstrip("\n").split(",")
            try:
                float(p[it])
                samples.append((float(p[iv]), float(p[ii])))
                score.append(f"{int(p[ic])},{p[ir]}\n")
            except (ValueError, IndexError):
                raise BadInput(f"{truth_csv}: line {n}: t_s, cycle, voltage_meas_v, current_meas_a or "
                               "r_film_ohm_m2 not a number")
    if not samples:
        raise BadInput(f"{truth_csv}: no samples")
    with open(os.path.join(out_dir, "measured.bin"), "wb") as f:
        f.write(MAGIC + struct.pack("<II", len(samples), 0))
        f.write(b"".join(struct.pack("<dd", v, i) for v, i in samples))
    with open(os.path.join(out_dir, "score_truth.csv"), "w") as f:
        f.writelines(score)
    return len(samples)


def read_run(path):
    """Rows (tick, mode, active, r_film, gain, nu, z) with the values decoded, and the summary."""
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
                         "film_rel_diff_pct": abs(f / d - 1) * 100, "film_err_m4f_pct": abs(f / t - 1) * 100,
                         "film_err_double_pct": abs(d / t - 1) * 100, "gain_m4f": m4f[k][4], "gain_double": b[4]})
    return ends


def run_timed(cmd, out_path, cwd=None):
    t0 = time.monotonic()
    with open(out_path, "w") as f:
        rc = subprocess.run(cmd, stdout=f, stderr=subprocess.PIPE, text=True, cwd=cwd).returncode
    return rc, time.monotonic() - t0


def qemu_cmd(a):
    return [a.qemu, "-M", a.machine, "-nographic", "-monitor", "none", "-serial", "none", "-semihosting",
            "-kernel", os.path.abspath(a.image)]


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


def check_runs(runs, ticks):
    (m4f, sm), (dbl, sd) = runs["m4f"], runs["double"]
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
    cycles, film = [int(r[0]) for r in rows], [float(r[1]) for r in rows]
    res["charge_ends"] = charge_ends(m4f, dbl, film, cycles)
    for e in res["charge_ends"]:
        if e["film_rel_diff_pct"] > a.limit_pct:
            res["failures"].append(f"charge end tick {e['tick']}: film M4F vs double {e['film_rel_diff_pct']:.4f} %")
    if "host_float" in runs:
        res["m4f_vs_host_float_identical_ticks"] = bit_identical(m4f, runs["host_float"][0])
    res["m4f_summary"], res["double_summary"] = runs["m4f"][1], runs["double"][1]
    os.remove(merged)
    return res


def one_truth(a, k, params):
    d = os.path.join(a.out, f"truth{k}")
    # This script's own folder of an earlier run (bmssim's --out refuses a folder holding the
    # converted streams and run outputs written beside truth.csv).
    shutil.rmtree(d, ignore_errors=True)
    os.makedirs(d, exist_ok=True)
    cmd = [a.bmssim, "simulate", "--cycles", str(a.cycles), "--noise-v-mv", str(a.noise_v_mv),
           "--seed", str(a.seed + k), "--quiet", "--out", d]
    for name, value in params.items():
        cmd += ["--set", f"{name}={value:.6g}"]
    t0 = time.monotonic()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    ticks = convert_truth(os.path.join(d, "truth.csv"), d, a.max_ticks)
    sim_s = time.monotonic() - t0
    runs, times = run_builds(a, d)
    check_runs(runs, ticks)
    res = score_truth(a, d, runs, ticks)
    res.update({"truth": k, "set": params, "command": " ".join(cmd), "ticks": ticks, "simulate_s": sim_s,
                "run_s": times, "qemu_ms_per_1000_ticks": times["m4f"] / ticks * 1e6})
    for name in ("truth.csv", "measured.bin", "m4f.txt", "double.txt", "host_float.txt"):
        if os.path.exists(os.path.join(d, name)):
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
    ap.add_argument("--limit-pct", type=float, default=0.5)
    return ap.parse_args()


def validate(a):
    for name in ("bmssim", "host_exe", "host_float_exe", "qemu"):
        exe = getattr(a, name)
        if exe and not os.access(exe, os.X_OK) and not (os.sep not in exe and shutil.which(exe)):
            raise BadInput(f"--{name.replace('_', '-')} {exe}: not an executable")
    if not os.path.isfile(a.image):
        raise BadInput(f"--image {a.image}: no such file")
    if a.truths < 1 or a.cycles < 1 or a.max_ticks < 0 or a.limit_pct <= 0 or a.noise_v_mv < 0:
        raise BadInput("--truths and --cycles must be >= 1, --max-ticks >= 0, --limit-pct > 0, --noise-v-mv >= 0")


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
               "noise_v_mv": a.noise_v_mv, "limit_pct": a.limit_pct, "machine": a.machine,
               "wall_s": time.monotonic() - t_start, "qemu_s": sum(c["run_s"]["m4f"] for c in cases),
               "failed": sum(1 for c in cases if c["failures"]), "cases": cases}
    with open(os.path.join(a.out, "summary.json"), "w") as f:
        json.dump(summary, f, indent=1)
    print(f"{a.truths} truths, {summary['failed']} failed; QEMU {summary['qemu_s']:.0f} s, wall "
          f"{summary['wall_s']:.0f} s; {os.path.join(a.out, 'summary.json')}")
    return 1 if summary["failed"] else 0


if __name__ == "__main__":
    sys.exit(main())
