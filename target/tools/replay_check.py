#!/usr/bin/python3
"""Runs and checks the replay application (target/replay_main.cpp); used by ctest.

  replay_check.py run --out FILE [--timeout S] -- COMMAND...
      Runs COMMAND (the host executable, or qemu-system-arm ... -kernel bms_replay.elf),
      writes its standard output to FILE, fails unless it exits 0 and printed every tick.
  replay_check.py compare --target FILE --host-exe EXE [--host-float-exe EXE] --scalar double|float
                          [--data CSV.gz] [--rtol 1e-9] [--max-film-median-rel 0.005] [--json OUT]
      Runs the host build of the same application and compares. Both runs must print the same
      firmware source hash (target/tools/source_hash.cmake): the reference is built from the
      image's sources. double: every number of every tick must equal the host's within rtol
      (relative; see tolerance() below), the integer columns exactly. float: the film
      estimate against the host's double build, median relative difference over constant-
      current charge, must be within --max-film-median-rel (the host's float build is
      reported beside it).
  replay_check.py cost --target FILE [--limit N] [--json OUT]
      Instructions per tick (last column; board runs under -icount shift=0): median and worst
      case over the cycle, RCSI active and idle, per mode; the Newton iteration counts and
      cap hits; the Newton-cap probe. Fails when the worst tick exceeds --limit.
Exit status: 0 pass, 1 check failed, 2 bad usage or missing input.
"""
import argparse
import gzip
import json
import math
import os
import statistics
import subprocess
import sys
import time

COLUMNS = ["tick", "mode", "rcsi_active", "r_film_est_ohm_m2", "z_v", "model_voltage_v", "model_current_a",
           "j_side_a_m3", "li_loss_ah", "theta_1", "theta_2", "status", "newton_iterations", "instructions"]
INT_COLUMNS = {"tick", "mode", "rcsi_active", "status", "newton_iterations"}
REAL_COLUMNS = [c for c in COLUMNS if c not in INT_COLUMNS and c != "instructions"]
MODE_NAMES = {0: "rest", 1: "cc_discharge", 2: "cv_discharge", 3: "cc_charge", 4: "cv_charge", 15: "unknown"}
NOT_CONVERGED_BIT = 1 << 12  # FwStatus::kModelNotConverged


class Run:
    def __init__(self, path):
        self.path = path
        self.rows = []
        self.summary = {}
        with open(path) as f:
            for line in f:
                if line.startswith("# columns"):
                    cols = line.split()[2:]
                    if cols != COLUMNS:
                        raise ValueError(f"{path}: unexpected columns {cols}")
                elif line.startswith("#"):
                    parts = line[1:].split(None, 1)
                    if parts:
                        self.summary[parts[0]] = parts[1].strip() if len(parts) > 1 else ""
                elif line.strip():
                    fields = line.split()
                    if len(fields) != len(COLUMNS):
                        raise ValueError(f"{path}: line {len(self.rows) + 1}: {len(fields)} fields")
                    self.rows.append(fields)
        self.ticks = int(self.summary.get("ticks", "-1"))

    def col(self, name):
        i = COLUMNS.index(name)
        conv = int if name in INT_COLUMNS or name == "instructions" else float
        return [conv(r[i]) for r in self.rows]


def fail(msg):
    print(f"replay_check: FAIL: {msg}")
    return 1


def cmd_run(a):
    if not a.command:
        print("replay_check run: no command", file=sys.stderr)
        return 2
    exe = a.command[0]
    if not os.path.exists(exe) and os.sep in exe:
        print(f"replay_check run: {exe} does not exist", file=sys.stderr)
        return 2
    os.makedirs(os.path.dirname(os.path.abspath(a.out)), exist_ok=True)
    t0 = time.monotonic()
    tmp = a.out + ".part"
    with open(tmp, "w") as out:
        try:
            p = subprocess.run(a.command, stdout=out, stderr=subprocess.PIPE, timeout=a.timeout)
        except subprocess.TimeoutExpired:
            return fail(f"{' '.join(a.command)}: no exit within {a.timeout} s")
    wall = time.monotonic() - t0
    if p.stderr:
        sys.stdout.write(p.stderr.decode(errors="replace"))
    if p.returncode != 0:
        return fail(f"{' '.join(a.command)}: exit status {p.returncode}")
    os.replace(tmp, a.out)
    run = Run(a.out)
    if run.ticks <= 0 or len(run.rows) != run.ticks:
        return fail(f"{a.out}: {len(run.rows)} tick lines, summary says {run.ticks}")
    print(f"replay_check: {len(run.rows)} ticks in {wall:.1f} s -> {a.out}")
    for k in ("scalar", "platform", "status_or", "newton_iterations_max", "newton_cap_hits", "stack_used_bytes",
              "libc_heap_used_bytes", "firmware_state_bytes"):
        if k in run.summary:
            print(f"  {k} {run.summary[k]}")
    return 0


def host_reference(exe, out_path):
    if not os.path.exists(exe):
        print(f"replay_check: the host reference {exe} does not exist: build the host preset first "
              f"(./bms build host, or set BMS_HOST_BUILD_DIR)", file=sys.stderr)
        return None
    with open(out_path + ".part", "w") as out:
        p = subprocess.run([exe], stdout=out, timeout=600)
    if p.returncode != 0:
        print(f"replay_check: {exe}: exit status {p.returncode}", file=sys.stderr)
        return None
    os.replace(out_path + ".part", out_path)
    return Run(out_path)


def tolerance(host_values, rtol):
    """|a - b| <= rtol * max(|b|, floor): relative, with a floor of 1e-6 of the column's largest
    magnitude over the run, so values that cross zero (z, theta_2) are compared at the scale of
    the column rather than relative to an accidental near-zero."""
    scale = max((abs(v) for v in host_values), default=0.0)
    return rtol, 1e-6 * scale


def compare_real(t_vals, h_vals, rtol, floor=None):
    rt, col_floor = tolerance(h_vals, rtol)
    floor = col_floor if floor is None else floor
    worst_rel, worst_abs, worst_tick, bad, identical = 0.0, 0.0, None, 0, 0
    for k, (x, y) in enumerate(zip(t_vals, h_vals)):
        if x == y or (math.isnan(x) and math.isnan(y)):
            identical += 1
            continue
        d = abs(x - y)
        rel = d / max(abs(y), floor) if max(abs(y), floor) > 0 else math.inf
        if not math.isfinite(x):
            rel = math.inf
        if rel > worst_rel:
            worst_rel, worst_tick = rel, k
        worst_abs = max(worst_abs, d)
        if rel > rt:
            bad += 1
    return {"identical": identical, "max_rel": worst_rel, "max_abs": worst_abs, "worst_tick": worst_tick,
            "over_tolerance": bad, "floor": floor}


def truth_film(data):
    if not data:
        return None
    with gzip.open(data, "rt") as f:
        lines = [l for l in f if not l.startswith("#")]
    head = lines[0].strip().split(",")
    i = head.index("r_film_ohm_m2")
    return [float(l.split(",")[i]) for l in lines[1:]]


def film_error(est, ref, modes):
    """Film-resistance error of est against ref: over all ticks and over constant-current charge."""
    out = {}
    for name, sel in (("all", lambda m: True), ("cc_charge", lambda m: m == 3)):
        d = [(abs(e - r), abs(e - r) / abs(r)) for e, r, m in zip(est, ref, modes) if sel(m) and r != 0.0]
        if not d:
            continue
        ab = [x[0] for x in d]
        rel = [x[1] for x in d]
        out[name] = {"ticks": len(d), "max_abs_ohm_m2": max(ab), "max_rel": max(rel),
                     "median_rel": statistics.median(rel), "end_rel": rel[-1]}
    out["end"] = {"estimate_ohm_m2": est[-1], "reference_ohm_m2": ref[-1]}
    return out


def cmd_compare(a):
    target = Run(a.target)
    if target.ticks <= 0 or len(target.rows) != target.ticks:
        return fail(f"{a.target}: incomplete run ({len(target.rows)} ticks)")
    work = os.path.dirname(os.path.abspath(a.json or a.target))
    host = host_reference(a.host_exe, os.path.join(work, "replay-host-double.txt"))
    if host is None:
        return 2
    if len(host.rows) != len(target.rows):
        return fail(f"{len(target.rows)} target ticks, {len(host.rows)} host ticks")
    result = {"target": a.target, "host_exe": a.host_exe, "scalar": a.scalar, "ticks": len(target.rows),
              "source_hash": {"target": target.summary.get("source_hash"), "host": host.summary.get("source_hash")}}
    failures = []
    th, hh = result["source_hash"]["target"], result["source_hash"]["host"]
    if not th or th != hh:
        failures.append(f"firmware source hash: target {th}, host reference {hh} (rebuild the host preset "
                        f"from the same sources)")
    else:
        print(f"replay_check: firmware source hash {th} on both")
    modes = host.col("mode")
    if a.scalar == "double":
        result["rtol"] = a.rtol
        result["identical_lines"] = sum(1 for x, y in zip(target.rows, host.rows) if x[:-1] == y[:-1])
        result["integer_mismatches"] = {}
        for c in sorted(INT_COLUMNS):
            n = sum(1 for x, y in zip(target.col(c), host.col(c)) if x != y)
            result["integer_mismatches"][c] = n
            if n:
                failures.append(f"{c} differs in {n} ticks")
        result["columns"] = {}
        # z = y_hat - y is a difference of two terminal voltages: it carries the model voltage's
        # rounding (a last-bit difference of a libm function between newlib and glibc is 1e-15 V),
        # so it is judged at the terminal voltage's scale, not at 1e-6 of its own largest value.
        v_scale = max(abs(v) for v in host.col("model_voltage_v"))
        for c in REAL_COLUMNS:
            r = compare_real(target.col(c), host.col(c), a.rtol, v_scale if c == "z_v" else None)
            result["columns"][c] = r
            if r["over_tolerance"]:
                failures.append(f"{c}: {r['over_tolerance']} ticks beyond {a.rtol:g} relative "
                                f"(worst {r['max_rel']:.3g} at tick {r['worst_tick']})")
        print(f"replay_check: {result['identical_lines']} of {len(target.rows)} tick lines identical to the host's")
        for c in REAL_COLUMNS:
            r = result["columns"][c]
            print(f"  {c:18s} identical {r['identical']:6d}  max rel {r['max_rel']:.3g}  max abs {r['max_abs']:.3g}")
    else:
        est = target.col("r_film_est_ohm_m2")
        if not all(math.isfinite(v) for v in est):
            failures.append("non-finite film-resistance estimate")
        result["film_vs_host_double"] = film_error(est, host.col("r_film_est_ohm_m2"), modes)
        result["theta_vs_host_double"] = {c: compare_real(target.col(c), host.col(c), 0.0) for c in ("theta_1", "theta_2")}
        result["mode_mismatches_vs_double"] = sum(1 for x, y in zip(target.col("mode"), modes) if x != y)
        if a.host_float_exe:
            hf = host_reference(a.host_float_exe, os.path.join(work, "replay-host-float.txt"))
            if hf is not None and hf.summary.get("source_hash") != th:
                failures.append(f"firmware source hash of {a.host_float_exe}: {hf.summary.get('source_hash')}, "
                                f"target {th}")
            if hf is not None:
                result["film_vs_host_float"] = compare_real(est, hf.col("r_film_est_ohm_m2"), 0.0)
                result["identical_lines_vs_host_float"] = sum(
                    1 for x, y in zip(target.rows, hf.rows) if x[:-1] == y[:-1])
        f = result["film_vs_host_double"]
        result["max_film_median_rel"] = a.max_film_median_rel
        cc = f.get("cc_charge")
        if cc is None:
            failures.append("no constant-current charge in the run")
        elif cc["median_rel"] > a.max_film_median_rel:
            failures.append(f"film estimate vs the host's double build: median {cc['median_rel']:.3g} relative over "
                            f"CC charge > {a.max_film_median_rel:g}")
        print(f"replay_check: float film resistance against the host's double build over {len(est)} ticks:")
        for k in ("all", "cc_charge"):
            if k in f:
                print(f"  {k:9s} max abs {f[k]['max_abs_ohm_m2']:.3g} ohm m2, max rel {f[k]['max_rel']:.3g}, "
                      f"median rel {f[k]['median_rel']:.3g}, end rel {f[k]['end_rel']:.3g}")
        print(f"  end: float {f['end']['estimate_ohm_m2']:.9g}, double {f['end']['reference_ohm_m2']:.17g}")
        print(f"  mode mismatches against double: {result['mode_mismatches_vs_double']}")
        if "film_vs_host_float" in result:
            r = result["film_vs_host_float"]
            print(f"  against the host's float build: {result['identical_lines_vs_host_float']} identical lines, "
                  f"film max rel {r['max_rel']:.3g}")
    truth = truth_film(a.data)
    if truth and len(truth) == len(target.rows):
        result["film_vs_truth"] = film_error(target.col("r_film_est_ohm_m2"), truth, modes)
        t = result["film_vs_truth"].get("cc_charge")
        if t:
            print(f"  (for orientation: estimate against the truth model in CC charge: median rel "
                  f"{t['median_rel']:.3g}, end rel {t['end_rel']:.3g})")
    result["failures"] = failures
    if a.json:
        with open(a.json, "w") as f:
            json.dump(result, f, indent=1)
    for m in failures:
        print(f"replay_check: FAIL: {m}")
    return 1 if failures else 0


def stats(values):
    if not values:
        return None
    s = sorted(values)
    return {"ticks": len(s), "median": statistics.median(s), "p99": s[min(len(s) - 1, int(0.99 * len(s)))],
            "max": s[-1]}


def cmd_cost(a):
    run = Run(a.target)
    if run.ticks <= 0 or len(run.rows) != run.ticks:
        return fail(f"{a.target}: incomplete run")
    cost = run.col("instructions")
    if max(cost) == 0:
        return fail(f"{a.target}: no instruction counts (a host run?)")
    modes, active, newton, status = run.col("mode"), run.col("rcsi_active"), run.col("newton_iterations"), run.col("status")
    worst_tick = max(range(len(cost)), key=lambda k: cost[k])
    res = {"target": a.target, "platform": run.summary.get("platform"), "scalar": run.summary.get("scalar"),
           "unit": "instructions (qemu -icount shift=0; SysTick resolution 40)",
           "counter_overhead": int(run.summary.get("counter_overhead_instructions", "0").split()[0]),
           "all": stats(cost), "worst_tick": worst_tick, "worst_tick_mode": MODE_NAMES.get(modes[worst_tick]),
           "rcsi_active": stats([c for c, x in zip(cost, active) if x == 1]),
           "rcsi_idle": stats([c for c, x in zip(cost, active) if x == 0]),
           "by_mode": {}, "newton_histogram": {}, "newton_cap_hits": sum(1 for s in status if s & NOT_CONVERGED_BIT),
           "by_newton_iterations": {}}
    for m in sorted(set(modes)):
        res["by_mode"][MODE_NAMES.get(m, str(m))] = stats([c for c, x in zip(cost, modes) if x == m])
    for n in sorted(set(newton)):
        res["newton_histogram"][str(n)] = sum(1 for x in newton if x == n)
        res["by_newton_iterations"][str(n)] = stats([c for c, x in zip(cost, newton) if x == n])
    probe = run.summary.get("newton_cap_probe", "").split()
    if len(probe) >= 6:
        res["newton_cap_probe"] = {"iterations": int(probe[1]), "converged": probe[3] == "1",
                                   "instructions": int(probe[5])}
        # A tick is: input checks, mode detection, estimator, one model step. Its bounded worst
        # case: the capped model step plus the most expensive tick that was not a CV step.
        non_cv = [c for c, n in zip(cost, newton) if n == 0]
        res["bounded_worst_tick"] = res["newton_cap_probe"]["instructions"] + (max(non_cv) if non_cv else 0)
    resync = run.summary.get("resync_probe", "").split()
    if len(resync) >= 4:
        # A re-synchronisation runs after the tick's own model step: bound = probe + the worst tick
        # that did not re-synchronise (a tick that did already holds one; the replay lists them,
        # and their measured cost is in max(cost), checked against the limit like every tick's).
        res["resync_probe"] = {"converged": resync[1] == "1", "instructions": int(resync[3])}
        listed = run.summary.get("resync_ticks")
        resynced = {int(x) for x in listed.split()} if listed else set()
        others = [c for k, c in enumerate(cost) if k not in resynced]
        res["resync_ticks"] = sorted(resynced) if listed is not None else None
        res["resync_ticks_max"] = max((cost[k] for k in resynced if k < len(cost)), default=0)
        res["resync_tick_bound"] = res["resync_probe"]["instructions"] + (max(others) if others else 0)
    gap = run.summary.get("catch_up_probe", "").split()
    if len(gap) >= 6:
        # The probe spans the 600 missed ticks and the tick that catches up; a missed tick
        # costs almost nothing (no sample), so this is the catching-up tick's cost.
        res["catch_up_probe"] = {"gap_ticks": int(gap[1]), "finite": gap[3] == "1", "instructions": int(gap[5])}
    res["limit"] = a.limit
    print(f"replay_check: instructions per tick on {res['platform']} ({res['scalar']}), {len(cost)} ticks:")
    print(f"  all          median {res['all']['median']:>8.0f}  max {res['all']['max']:>8d}  "
          f"(tick {worst_tick}, {res['worst_tick_mode']})")
    for k in ("rcsi_active", "rcsi_idle"):
        if res[k]:
            print(f"  {k:12s} median {res[k]['median']:>8.0f}  max {res[k]['max']:>8d}  ({res[k]['ticks']} ticks)")
    for m, s in res["by_mode"].items():
        print(f"  {m:12s} median {s['median']:>8.0f}  max {s['max']:>8d}  ({s['ticks']} ticks)")
    print(f"  Newton iterations per tick: {res['newton_histogram']}; cap hits (not converged): {res['newton_cap_hits']}")
    if "newton_cap_probe" in res:
        p = res["newton_cap_probe"]
        print(f"  CV step at the Newton cap ({p['iterations']} iterations): {p['instructions']} instructions; "
              f"bounded worst tick {res['bounded_worst_tick']}")
    if "resync_probe" in res:
        print(f"  state re-synchronisation (beyond-paper, once per CV phase): {res['resync_probe']['instructions']} "
              f"instructions (converged {res['resync_probe']['converged']}); tick bound with it "
              f"{res['resync_tick_bound']}")
        if res.get("resync_ticks") is not None:
            print(f"  ticks that re-synchronised in the replay: {len(res['resync_ticks'])}, the most expensive "
                  f"{res['resync_ticks_max']} instructions (the bound adds the probe to the other ticks)")
    if "catch_up_probe" in res:
        print(f"  tick after a {res['catch_up_probe']['gap_ticks']}-tick gap (catch-up; the 600 missed ticks "
              f"included): {res['catch_up_probe']['instructions']} instructions (finite {res['catch_up_probe']['finite']})")
    failures = []
    if a.limit and res["all"]["max"] > a.limit:
        failures.append(f"worst tick {res['all']['max']} > {a.limit} instructions")
    if a.limit and res.get("resync_tick_bound", 0) > a.limit:
        failures.append(f"tick with a re-synchronisation up to {res['resync_tick_bound']} > {a.limit} instructions")
    if a.limit and res.get("catch_up_probe", {}).get("instructions", 0) > a.limit:
        failures.append(f"catch-up tick {res['catch_up_probe']['instructions']} > {a.limit} instructions")
    if "resync_probe" in res and not (res["resync_probe"]["converged"] and res["catch_up_probe"]["finite"]):
        failures.append("the re-synchronisation probe did not converge or the catch-up tick was not finite")
    if a.limit and "bounded_worst_tick" in res and res["bounded_worst_tick"] > a.limit:
        failures.append(f"bounded worst tick {res['bounded_worst_tick']} > {a.limit} instructions")
    res["failures"] = failures
    if a.json:
        with open(a.json, "w") as f:
            json.dump(res, f, indent=1)
    for m in failures:
        print(f"replay_check: FAIL: {m}")
    return 1 if failures else 0


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    sub = ap.add_subparsers(dest="cmd", required=True)
    r = sub.add_parser("run")
    r.add_argument("--out", required=True)
    r.add_argument("--timeout", type=float, default=600)
    r.add_argument("command", nargs=argparse.REMAINDER)
    c = sub.add_parser("compare")
    c.add_argument("--target", required=True)
    c.add_argument("--host-exe", required=True)
    c.add_argument("--host-float-exe")
    c.add_argument("--scalar", choices=["double", "float"], required=True)
    c.add_argument("--data")
    c.add_argument("--rtol", type=float, default=1e-9)
    c.add_argument("--max-film-median-rel", type=float, default=0.005)
    c.add_argument("--json")
    k = sub.add_parser("cost")
    k.add_argument("--target", required=True)
    k.add_argument("--limit", type=int, default=0)
    k.add_argument("--json")
    a = ap.parse_args()
    if a.cmd == "run" and a.command and a.command[0] == "--":
        a.command = a.command[1:]
    try:
        return {"run": cmd_run, "compare": cmd_compare, "cost": cmd_cost}[a.cmd](a)
    except (OSError, ValueError) as e:
        print(f"replay_check: {e}", file=sys.stderr)
        return 2


if __name__ == "__main__":
    sys.exit(main())
