#!/usr/bin/env python3
"""The discharge-onset resistance's agreement with the cycler's internal resistance, against the
time after the step it is referred to.

Reads Arbin exports (Step_Time(s), Current(A) charge-positive, Voltage(V), Internal_Resistance)
of one cell, finds each rest-to-discharge step from a full cell (rest voltage over --full-v),
and refers the drop over the current at the first two samples under the step to a time tau
after the step on sqrt(time since the step), as `bmssim estimate` does for tau = 0
(r_discharge_onset_ohm). Prints, per tau, Pearson r and the slope of the growth regressed on the
cycler's internal-resistance growth (the last nonzero value logged before the step).

Usage: scripts/discharge-onset-sensitivity.py ../shared/data/calce-cs2-35 [--full-v 4.0]
"""
import argparse
import csv
import datetime
import glob
import math
import os
import sys


def first_date(path):
    with open(path, newline="") as f:
        rows = csv.reader(f)
        next(rows)
        return datetime.datetime.strptime(next(rows)[2], "%Y-%m-%d %H:%M:%S")


def steps(path, full_v):
    with open(path, newline="") as f:
        rows = list(csv.DictReader(f))
    ir = math.nan
    for k in range(1, len(rows) - 1):
        prev, row, nxt = rows[k - 1], rows[k], rows[k + 1]
        if float(prev["Internal_Resistance(Ohm)"]) != 0.0:
            ir = float(prev["Internal_Resistance(Ohm)"])
        i0, i1, i2 = (-float(r["Current(A)"]) for r in (prev, row, nxt))
        if abs(i0) > 0.011 or i1 < 0.5 or i2 < 0.5 or float(prev["Voltage(V)"]) < full_v:
            continue
        tau1, tau2 = float(row["Step_Time(s)"]), float(nxt["Step_Time(s)"])
        if not tau2 > tau1:
            continue
        v0 = float(prev["Voltage(V)"])
        r1, r2 = (v0 - float(row["Voltage(V)"])) / i1, (v0 - float(nxt["Voltage(V)"])) / i2
        yield tau1, tau2, r1, r2, ir


def fit(x, y):
    mx, my = sum(x) / len(x), sum(y) / len(y)
    sxy = sum((a - mx) * (b - my) for a, b in zip(x, y))
    sxx = sum((a - mx) ** 2 for a in x)
    syy = sum((b - my) ** 2 for b in y)
    return sxy / math.sqrt(sxx * syy), sxy / sxx


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("data")
    ap.add_argument("--full-v", type=float, default=4.0)
    a = ap.parse_args()
    files = glob.glob(os.path.join(a.data, "*_Channel_*.csv"))
    if not files:
        sys.exit(f"{a.data}: no Arbin *_Channel_*.csv files")
    found = [s for f in sorted(files, key=first_date) for s in steps(f, a.full_v)]
    found = [s for s in found if math.isfinite(s[4])]
    print(f"{len(found)} discharge steps from a full cell; first-sample delay "
          f"{min(s[0] for s in found):.1f}-{max(s[0] for s in found):.1f} s")
    print("tau_s  pearson_r  slope")
    ir = [s[4] - found[0][4] for s in found]
    for tau in (0.0, 1.0, 5.0, 10.0, 20.0, 30.0):
        r = [r1 + (r2 - r1) * (math.sqrt(tau) - math.sqrt(t1)) / (math.sqrt(t2) - math.sqrt(t1))
             for t1, t2, r1, r2, _ in found]
        p, slope = fit(ir, [v - r[0] for v in r])
        print(f"{tau:5.0f}  {p:9.3f}  {slope:5.2f}")


if __name__ == "__main__":
    main()
