#!/usr/bin/python3
"""Float against double on blind truths: draws truths from the blind study's set-1 ranges
(docs/results/blind.md: initial film U(0.8, 1.2) x nominal, film-growth law U(0.3, 3), side-
reaction i0 U(0.5, 2), inventory U(0.99, 1.01)), simulates each, runs the best profile's tick in
float and in double over the measured columns (bms_float_check) and scores both against the
truth (float_check.py).

  float_blind.py --bmssim EXE --check EXE --out DIR [--truths 10] [--cycles 5] [--seed 1]
                 [--noise-v-mv 0.2] [--limit-pct 0.5]

Writes DIR/summary.json (every truth's draw and scores) and prints one line per truth and the
worst differences. Exit 1 when a truth fails float_check's limits, 2 on bad usage.
"""
import argparse
import json
import os
import random
import subprocess
import sys

NOMINAL_FILM_OHM_M2 = 3.391e-3
HERE = os.path.dirname(os.path.abspath(__file__))


def draw(rng):
    return {"r_film_initial_ohm_m2": NOMINAL_FILM_OHM_M2 * rng.uniform(0.8, 1.2),
            "film_growth_scale": rng.uniform(0.3, 3.0), "side_i0_scale": rng.uniform(0.5, 2.0),
            "inventory_scale": rng.uniform(0.99, 1.01)}


def run_truth(a, k, params):
    d = os.path.join(a.out, f"truth{k}")
    cmd = [a.bmssim, "simulate", "--cycles", str(a.cycles), "--noise-v-mv", str(a.noise_v_mv),
           "--seed", str(a.seed + k), "--quiet", "--out", d]
    for name, value in params.items():
        cmd += ["--set", f"{name}={value:.6g}"]
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
    truth = os.path.join(d, "truth.csv")
    run = os.path.join(d, "float_check.txt")
    with open(run, "w") as f:
        subprocess.run([a.check, truth], check=True, stdout=f)
    score = os.path.join(d, "float_check.json")
    p = subprocess.run([sys.executable, os.path.join(HERE, "float_check.py"), "--run", run, "--truth", truth,
                        "--json", score, "--limit-pct", str(a.limit_pct)], stdout=subprocess.PIPE, text=True)
    with open(score) as f:
        res = json.load(f)
    os.remove(run)  # 100 MB per truth; the scores are kept
    os.remove(truth)
    return res, p.returncode, " ".join(cmd)


def worst_cycle_err(errs, skip):
    vals = [v for c, v in errs.items() if int(c) > skip]
    return max(vals) if vals else None


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bmssim", required=True)
    ap.add_argument("--check", required=True)
    ap.add_argument("--out", required=True)
    ap.add_argument("--truths", type=int, default=10)
    ap.add_argument("--cycles", type=int, default=5)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--noise-v-mv", type=float, default=0.2)
    ap.add_argument("--limit-pct", type=float, default=0.5)
    a = ap.parse_args()
    for exe in (a.bmssim, a.check):
        if not os.access(exe, os.X_OK):
            print(f"float_blind: {exe}: not an executable", file=sys.stderr)
            return 2
    os.makedirs(a.out, exist_ok=True)
    rng = random.Random(a.seed)
    cases, failed = [], 0
    print("truth  film f-vs-d median %  film err % (worst of cycles 3+) float/double  growth_err_pct float/double  "
          "gain float/double")
    for k in range(a.truths):
        params = draw(rng)
        res, rc, cmd = run_truth(a, k, params)
        failed += rc != 0
        ef = worst_cycle_err(res["float"]["film_err_median_pct"], 2)
        ed = worst_cycle_err(res["double"]["film_err_median_pct"], 2)
        gf, gd = res["float"]["growth_err_pct"], res["double"]["growth_err_pct"]
        print(f"{k:5d}  {res['film_float_vs_double_pct']['median']:.4f}  {ef:.3f} / {ed:.3f}  "
              f"{gf:.2f} / {gd:.2f}  {res['float']['gain_end']:.4f} / {res['double']['gain_end']:.4f}"
              + ("  FAIL" if rc else ""))
        cases.append({"truth": k, "set": params, "command": cmd, "scores": res, "float_check_exit": rc})
    def worst(f):
        return max(f(c["scores"]) for c in cases)
    summary = {"truths": a.truths, "cycles": a.cycles, "noise_v_mv": a.noise_v_mv, "seed": a.seed,
               "worst_film_float_vs_double_median_pct": worst(lambda s: s["film_float_vs_double_pct"]["median"]),
               "worst_film_err_difference_pp": worst(lambda s: max(
                   abs(s["float"]["film_err_median_pct"][c] - s["double"]["film_err_median_pct"][c])
                   for c in s["double"]["film_err_median_pct"])),
               "worst_growth_err_difference_pp": worst(lambda s: abs(s["float"]["growth_err_pct"] -
                                                                    s["double"]["growth_err_pct"])),
               "worst_gain_difference_pct": worst(lambda s: abs(s["float"]["gain_end"] / s["double"]["gain_end"] - 1) * 100),
               "cases": cases, "failed": failed}
    with open(os.path.join(a.out, "summary.json"), "w") as f:
        json.dump(summary, f, indent=1)
    print(f"worst over {a.truths} truths: film float vs double median {summary['worst_film_float_vs_double_median_pct']:.4f} %, "
          f"film error difference {summary['worst_film_err_difference_pp']:.3f} points, growth_err_pct difference "
          f"{summary['worst_growth_err_difference_pp']:.3f} points, gain {summary['worst_gain_difference_pct']:.3f} %")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
