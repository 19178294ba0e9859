#!/usr/bin/python3
"""Scores bms_float_check's output (the best profile's tick in float and in double over the
measured columns of a truth.csv) against each other and against the truth.

  float_check.py --run OUT.txt --truth TRUTH.csv [--json FILE] [--limit-pct 0.5]

Reports, with the estimator's own mode (the double core's) selecting constant-current charge:
  - film estimate float vs double: relative difference per CC-charge tick, median and max,
    overall and per cycle;
  - blind identification, each build against the truth: film error (median over each CC
    charge, as `bmssim estimate` scores it), growth_err_pct (contract definition), the
    identified growth gain and inventory deviation at the end;
and fails (exit 1) when the float-vs-double median exceeds --limit-pct, or when a float
accuracy figure (per-cycle film error, growth_err_pct) is more than --limit-pct percentage
points from double's. Exit 2: bad input.
"""
import argparse
import json
import math
import statistics
import sys

CC_CHARGE = 3


def read_run(path):
    rows, summary, cols = [], {}, None
    with open(path) as f:
        for line in f:
            if line.startswith("# columns"):
                cols = line.split()[2:]
            elif line.startswith("#"):
                parts = line[1:].split(None, 1)
                summary[parts[0]] = parts[1].strip() if len(parts) > 1 else ""
            elif line.strip():
                rows.append(line.split())
    if cols is None:
        raise ValueError(f"{path}: no '# columns' line")
    out = {c: [] for c in cols}
    for n, r in enumerate(rows):
        if len(r) != len(cols):
            raise ValueError(f"{path}: tick line {n + 1}: {len(r)} fields, expected {len(cols)}")
        for c, v in zip(cols, r):
            out[c].append(float(v))
    return out, summary


def read_truth(path):
    with open(path) as f:
        head = f.readline().strip().split(",")
        try:
            ic, ir = head.index("cycle"), head.index("r_film_ohm_m2")
        except ValueError:
            raise ValueError(f"{path}: line 1: needs the cycle and r_film_ohm_m2 columns")
        cycle, film = [], []
        for line in f:
            p = line.split(",")
            cycle.append(int(p[ic]))
            film.append(float(p[ir]))
    return cycle, film


def rel_pct(f, d):
    """|f - d| / |d| in percent; a film estimate may pass through 0 in a learning start's swing
    (0 against 0: no difference; against a nonzero value: infinite)."""
    if d == 0.0:
        return 0.0 if f == 0.0 else math.inf
    return abs(f - d) / abs(d) * 100.0


def cycle_errors(est, truth, mode, cycle):
    per = {}
    for e, t, m, c in zip(est, truth, mode, cycle):
        if m == CC_CHARGE and t != 0.0:
            per.setdefault(c, []).append(abs(e - t) / t * 100.0)
    return {c: statistics.median(v) for c, v in sorted(per.items())}


def growth_err_pct(est, truth, mode, active):
    ends, first_learning_end, learned = [], None, False
    for i, m in enumerate(mode):
        if m != CC_CHARGE:
            continue
        learned = learned or active[i] == 1
        if i + 1 < len(mode) and mode[i + 1] == CC_CHARGE:
            continue
        ends.append(i)
        if learned and first_learning_end is None:
            first_learning_end = i
    if first_learning_end is None or ends[-1] == first_learning_end:
        return None
    r, e = first_learning_end, ends[-1]
    dt = truth[e] - truth[r]
    return abs((est[e] - est[r]) - dt) / abs(dt) * 100.0 if dt != 0 else None


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--run", required=True)
    ap.add_argument("--truth", required=True)
    ap.add_argument("--json")
    ap.add_argument("--limit-pct", type=float, default=0.5)
    a = ap.parse_args()
    try:
        run, summary = read_run(a.run)
        cycle, truth = read_truth(a.truth)
    except (OSError, ValueError) as e:
        print(f"float_check: {e}", file=sys.stderr)
        return 2
    if len(cycle) != len(run["tick"]):
        print(f"float_check: {a.run} has {len(run['tick'])} ticks, {a.truth} {len(cycle)} rows", file=sys.stderr)
        return 2
    mode = [int(m) for m in run["mode_d"]]
    rf, rd = run["r_film_f"], run["r_film_d"]
    rel = [rel_pct(f, d) for f, d, m in zip(rf, rd, mode) if m == CC_CHARGE]
    per_cycle = {}
    for f, d, m, c in zip(rf, rd, mode, cycle):
        if m == CC_CHARGE:
            per_cycle.setdefault(c, []).append(rel_pct(f, d))
    res = {"run": a.run, "truth": a.truth, "ticks": len(mode), "cc_charge_ticks": len(rel),
           "mode_mismatches": sum(1 for x, y in zip(run["mode_f"], run["mode_d"]) if x != y),
           "film_float_vs_double_pct": {"median": statistics.median(rel), "max": max(rel),
                                        "per_cycle_median": {c: statistics.median(v) for c, v in per_cycle.items()}},
           "summary": summary}
    for name, key in (("float", "f"), ("double", "d")):
        est = run["r_film_" + key]
        act = [int(x) for x in run["active_" + key]]
        res[name] = {"film_err_median_pct": cycle_errors(est, truth, mode, cycle),
                     "growth_err_pct": growth_err_pct(est, truth, mode, act),
                     "gain_end": run["gain_" + key][-1], "inventory_deviation_end": run["nu_" + key][-1]}
    failures = []
    if res["film_float_vs_double_pct"]["median"] > a.limit_pct:
        failures.append(f"film float vs double: median {res['film_float_vs_double_pct']['median']:.3f} % "
                        f"> {a.limit_pct} %")
    for c, ed in res["double"]["film_err_median_pct"].items():
        ef = res["float"]["film_err_median_pct"].get(c)
        if ef is None or abs(ef - ed) > a.limit_pct:
            failures.append(f"cycle {c}: film error float {ef} % vs double {ed:.3f} %")
    gf, gd = res["float"]["growth_err_pct"], res["double"]["growth_err_pct"]
    if gd is not None and (gf is None or abs(gf - gd) > a.limit_pct):
        failures.append(f"growth_err_pct float {gf} vs double {gd:.3f}")
    res["failures"] = failures
    f = res["film_float_vs_double_pct"]
    print(f"float_check: film float vs double over {len(rel)} CC-charge ticks: median {f['median']:.4f} %, "
          f"max {f['max']:.4f} %; per cycle median "
          + ", ".join(f"{c}: {v:.4f}" for c, v in f["per_cycle_median"].items()))
    for name in ("float", "double"):
        r = res[name]
        g = "none" if r["growth_err_pct"] is None else f"{r['growth_err_pct']:.3f}"
        print(f"  {name:6s} film err % per cycle " + ", ".join(f"{c}: {v:.3f}" for c, v in r["film_err_median_pct"].items())
              + f"; growth_err_pct {g}; gain {r['gain_end']:.6g}; inventory {r['inventory_deviation_end']:.6g}")
    print(f"  mode mismatches {res['mode_mismatches']}; " +
          ", ".join(f"{k} {summary[k]}" for k in sorted(summary) if "cap_hits" in k or "resyncs" in k))
    if a.json:
        with open(a.json, "w") as fj:
            json.dump(res, fj, indent=1)
    for m in failures:
        print(f"float_check: FAIL: {m}")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
