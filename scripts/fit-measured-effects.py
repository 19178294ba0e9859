#!/usr/bin/env python3
"""Fit truth-model effects to the About:Energy LFP 18650 discharges (docs/results/measured-effects.md).

Runs `bmssim simulate --cell aboutenergy --protocol csv:FILE --effect ...` for each measured
case and reports the voltage RMSE (model samples against the measured samples at the same
times, as `bmssim validate` does). Modes:

  eval   --effect NAME=VALUE ...            RMSE per case for one effect set
  sweep  --param NAME --values V1,V2,...    RMSE per case for each value of one effect
         [--effect NAME=VALUE ...]          (other effects held), fit case = --fit-case
  residual --effect ... --out DIR           writes DIR/residual_CASE.dat (t, Ah, V_meas,
                                            V_model, residual mV, T_K) for plotting

Only the standard library; one bmssim process at a time.
"""
import argparse
import csv
import json
import math
import os
import subprocess
import sys
import tempfile

CASES = {"C/20": "LFP_25degC_Co20.csv", "1C": "LFP_25degC_1C.csv", "2C": "LFP_25degC_2C.csv"}


def read_measured(path):
    t, i, v = [], [], []
    with open(path) as f:
        r = csv.reader(f)
        next(r)
        for row in r:
            t.append(float(row[0]))
            i.append(float(row[1]))
            v.append(float(row[2]))
    return t, i, v


def scaled_bpx(shared, scales, folder):
    """A copy of the BPX set (in a temporary folder, never in the repository) with numeric
    fields multiplied: scales = ["Positive electrode.Diffusivity [m2.s-1]=0.3", ...]."""
    src = os.path.join(shared, "data/aboutenergy-lfp18650/lfp_18650_cell_BPX.json")
    with open(src) as f:
        bpx = json.load(f)
    for s in scales:
        key, factor = s.rsplit("=", 1)
        section, field = key.split(".", 1)
        node = bpx["Parameterisation"][section]
        if not isinstance(node.get(field), (int, float)):
            sys.exit(f"fit-measured-effects: --scale '{s}': {section}/{field} is not a number in the BPX file")
        node[field] = node[field] * float(factor)
    path = os.path.join(folder, "scaled.bpx.json")
    with open(path, "w") as f:
        json.dump(bpx, f)
    return path


def simulate(bmssim, shared, case, effects, extra, scales=()):
    data = os.path.join(shared, "data/aboutenergy-lfp18650", CASES[case])
    with tempfile.TemporaryDirectory() as out:
        cell = scaled_bpx(shared, scales, out) if scales else "aboutenergy"
        cmd = [bmssim, "simulate", "--cell", cell, "--protocol", "csv:" + data, "--out", out, "--quiet"]
        for e in effects:
            cmd += ["--effect", e]
        cmd += extra
        env = dict(os.environ, BMS_SHARED_DIR=shared)
        res = subprocess.run(cmd, capture_output=True, text=True, env=env)
        if res.returncode != 0:
            raise RuntimeError(f"{' '.join(cmd)}: exit {res.returncode}: {res.stderr.strip()}")
        with open(os.path.join(out, "truth.csv")) as f:
            rows = list(csv.DictReader(f))
    return data, rows


WINDOW = None  # (from, to) in Ah: restrict the RMSE to that part of the discharge


def compare(data, rows):
    t, i, v = read_measured(data)
    index = {round(x, 6): k for k, x in enumerate(t)}
    out = []
    q = 0.0
    for r in rows:
        k = index.get(round(float(r["t_s"]), 6))
        if k is None:
            continue
        out.append((t[k], float(r["charge_ah"]), v[k], float(r["voltage_v"]), float(r["temperature_k"])))
    sel = out if WINDOW is None else [x for x in out if WINDOW[0] <= x[1] <= WINDOW[1]]
    sq = [(m - s) ** 2 for _, _, s, m, _ in sel]
    rmse = 1e3 * math.sqrt(sum(sq) / len(sq)) if sq else float("nan")
    return rmse, out, len(t) - len(out)


def run_cases(a, effects, cases):
    res = {}
    for c in cases:
        data, rows = simulate(a.bmssim, a.shared, c, effects, a.extra, a.scale)
        rmse, pts, early = compare(data, rows)
        res[c] = (rmse, pts, early)
    return res


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("mode", choices=["eval", "sweep", "residual"])
    p.add_argument("--bmssim", default="build/host/host_sim/bmssim")
    p.add_argument("--shared", default="../shared")
    p.add_argument("--effect", action="append", default=[], help="NAME=VALUE held in every run")
    p.add_argument("--scale", action="append", default=[],
                   help="'Section.Field=FACTOR': multiply a numeric BPX field (temporary copy of the set)")
    p.add_argument("--param", help="effect swept (sweep mode)")
    p.add_argument("--values", help="comma-separated values (sweep mode)")
    p.add_argument("--fit-case", default="1C", choices=list(CASES), help="case the sweep minimises")
    p.add_argument("--cases", default="C/20,1C,2C")
    p.add_argument("--out", help="folder for residual files (residual mode)")
    p.add_argument("--extra", nargs=argparse.REMAINDER, default=[], help="further bmssim simulate options")
    p.add_argument("--window-ah", help="FROM,TO: RMSE only where the discharged charge is in [FROM, TO] Ah")
    a = p.parse_args()
    if a.window_ah:
        global WINDOW
        WINDOW = tuple(float(x) for x in a.window_ah.split(","))
    if not os.access(a.bmssim, os.X_OK):
        sys.exit(f"fit-measured-effects: bmssim '{a.bmssim}' is not executable (build it, or pass --bmssim)")
    cases = a.cases.split(",")
    for c in cases:
        if c not in CASES:
            sys.exit(f"fit-measured-effects: --cases: unknown case '{c}' (use {', '.join(CASES)})")

    if a.mode == "eval" or a.mode == "residual":
        res = run_cases(a, a.effect, cases)
        print("effects: " + (" ".join(a.effect) or "none") + ("; scaled: " + " ".join(a.scale) if a.scale else ""))
        for c in cases:
            rmse, pts, early = res[c]
            print(f"  {c:5s} RMSE {rmse:8.2f} mV  end T {pts[-1][4]:.2f} K" +
                  (f"  (model stopped {early} samples early)" if early else ""))
        if a.mode == "residual":
            if not a.out:
                sys.exit("fit-measured-effects: residual mode needs --out DIR")
            os.makedirs(a.out, exist_ok=True)
            for c in cases:
                name = c.replace("/", "_")
                with open(os.path.join(a.out, f"residual_{name}.dat"), "w") as f:
                    f.write("# t_s charge_ah v_meas_v v_model_v residual_mv temperature_k\n")
                    for t, q, vm, vs, tk in res[c][1]:
                        f.write(f"{t} {q} {vm} {vs} {1e3 * (vs - vm)} {tk}\n")
        return

    if not a.param or not a.values:
        sys.exit("fit-measured-effects: sweep mode needs --param and --values")
    best = None
    print(f"sweep {a.param} (fit on {a.fit_case}); held: " + (" ".join(a.effect) or "none"))
    print("  value      " + "  ".join(f"{c:>9s}" for c in cases))
    for val in a.values.split(","):
        effects = a.effect + [f"{a.param}={val}"]
        try:
            res = run_cases(a, effects, cases)
        except RuntimeError as e:
            print(f"  {val:10s} failed: {e}")
            continue
        row = "  ".join(f"{res[c][0]:9.2f}" for c in cases)
        print(f"  {val:10s} {row}")
        if a.fit_case in res and (best is None or res[a.fit_case][0] < best[1]):
            best = (val, res[a.fit_case][0], {c: res[c][0] for c in cases})
    if best:
        print(f"best on {a.fit_case}: {a.param}={best[0]}; validation: " +
              ", ".join(f"{c} {best[2][c]:.2f} mV" for c in cases if c != a.fit_case))


if __name__ == "__main__":
    main()
