#!/usr/bin/env python3
"""How well a design-time bias table made from one run fits the CC charges of other runs.

Each RUN is a pair TRUTH_DIR:ESTIMATE_DIR: a `bmssim simulate` output (truth.csv, whose
`stoich_neg` is the abscissa) and a learning-off `bmssim estimate --no-learning` of it
(estimates.csv: `z_v`, the residual with no bias removed). The first run is the reference: its
learning ticks (CC charge, after the warm-up, cycles 2 on) give a table of z / I over 24 knots,
medians per knot, as host_sim/src/estimation/design_bias.cpp builds it (but over the truth's
stoichiometry, not the reduced model's). For every run the script prints the 50th / 90th
percentile of |z - table(x) I| and of |z - constant I| (the reference's median z / I) over its
learning ticks, in mV. Used by docs/results/envelope.md, "Partial charges against the
design-time calibration".

usage: partial-charge-table-fit.py [--warmup-s 900] REF_TRUTH:REF_EST RUN_TRUTH:RUN_EST ...
"""
import argparse
import csv
import sys

KNOTS = 24


def learning_ticks(pair, warmup_s):
    truth_dir, est_dir = pair.split(":", 1)
    stoich = {}
    with open(f"{truth_dir}/truth.csv", newline="") as f:
        for row in csv.DictReader(f):
            stoich[round(float(row["t_s"]), 1)] = float(row["stoich_neg"])
    ticks, start = [], None
    with open(f"{est_dir}/estimates.csv", newline="") as f:
        for row in csv.DictReader(f):
            if row["mode"] != "cc_charge":
                start = None
                continue
            t = float(row["t_s"])
            start = t if start is None else start
            x = stoich.get(round(t, 1))
            if int(row["cycle"]) >= 2 and t - start > warmup_s and x is not None:
                ticks.append((x, float(row["z_v"]), -float(row["model_current_a"])))
    if not ticks:
        sys.exit(f"partial-charge-table-fit: {pair}: no CC-charge tick after the warm-up in cycles 2 on")
    return ticks


def fill(medians):
    for k, m in enumerate(medians):
        if m is not None:
            continue
        a = next((i for i in range(k - 1, -1, -1) if medians[i] is not None), None)
        b = next((i for i in range(k + 1, KNOTS) if medians[i] is not None), None)
        medians[k] = medians[b] if a is None else medians[a] if b is None else \
            medians[a] + (medians[b] - medians[a]) * (k - a) / (b - a)
    return medians


def table_of(ticks):
    lo, hi = min(t[0] for t in ticks), max(t[0] for t in ticks)
    step = (hi - lo) / (KNOTS - 1)
    bins = [[] for _ in range(KNOTS)]
    for x, z, i in ticks:
        bins[min(KNOTS - 1, max(0, round((x - lo) / step)))].append(z / i)
    med = fill([sorted(b)[len(b) // 2] if b else None for b in bins])

    def at(x):
        s = (x - lo) / step
        if s <= 0:
            return med[0]
        if s >= KNOTS - 1:
            return med[-1]
        k = int(s)
        return med[k] + (s - k) * (med[k + 1] - med[k])
    return at


def pct(values, q):
    v = sorted(values)
    return v[int(q * (len(v) - 1) + 0.5)]


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--warmup-s", type=float, default=900.0)
    ap.add_argument("runs", nargs="+", help="TRUTH_DIR:ESTIMATE_DIR, the reference first")
    a = ap.parse_args()
    for r in a.runs:
        if ":" not in r:
            ap.error(f"'{r}' is not TRUTH_DIR:ESTIMATE_DIR")
    ref = learning_ticks(a.runs[0], a.warmup_s)
    at = table_of(ref)
    constant = sorted(z / i for _, z, i in ref)[len(ref) // 2]
    print(f"reference {a.runs[0]}: {len(ref)} ticks, constant {constant:.4e} ohm")
    print("run | ticks | table p50 / p90 [mV] | constant p50 / p90 [mV]")
    for r in a.runs:
        t = learning_ticks(r, a.warmup_s)
        e = [1e3 * abs(z - at(x) * i) for x, z, i in t]
        c = [1e3 * abs(z - constant * i) for _, z, i in t]
        print(f"{r} | {len(t)} | {pct(e, .5):.2f} / {pct(e, .9):.2f} | {pct(c, .5):.2f} / {pct(c, .9):.2f}")


if __name__ == "__main__":
    main()
