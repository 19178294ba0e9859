#!/usr/bin/env python3
"""growth_err_pct taken apart (docs/results/firmware-model.md, "Any cell: why growth_err_pct is
hundreds of percent"): for each run, between the contract's reference (the end of the first CC
charge the estimator learned in) and the end of the last CC charge, the estimated film change
split into the identified level's move (film_initial_est) and the growth law's part
(growth_gain_est x G, G the nominal law's integral), against the truth's change; and over the
seeds, the sd of the estimated change (the noise floor of the difference).
Usage: growth_decomposition.py OUT_DIR CELL SEED... (OUT_DIR/CELL-SEED/est/estimates.csv)"""
import csv, statistics, sys


def ref_and_last(path):
    rows = list(csv.DictReader(open(path)))
    ends, first, learned = [], None, False
    for i, r in enumerate(rows):
        if r["mode"] != "cc_charge":
            continue
        learned = learned or r["rcsi_active"] == "1"
        if i + 1 == len(rows) or rows[i + 1]["mode"] != "cc_charge":
            ends.append(r)
            if learned and first is None:
                first = len(ends) - 1
            learned = False
    return ends[first], ends[-1]


out, cell, seeds = sys.argv[1], sys.argv[2], sys.argv[3:]
f = lambda r, k: float(r[k])
est = []
print("| cell | seed | true change, ohm m2 | estimated change | of it: level (R0) move | of it: growth law (g G) | g at the end | growth_err_pct |")
print("|---|---|---|---|---|---|---|---|")
for s in seeds:
    a, b = ref_and_last(f"{out}/{cell}-{s}/est/estimates.csv")
    dt = f(b, "r_film_true_ohm_m2") - f(a, "r_film_true_ohm_m2")
    de = f(b, "r_film_est_ohm_m2") - f(a, "r_film_est_ohm_m2")
    dl = f(b, "film_initial_est_ohm_m2") - f(a, "film_initial_est_ohm_m2")
    est.append(de)
    print(f"| {cell} | {s} | {dt:.3e} | {de:.3e} | {dl:.3e} | {de - dl:.3e} | {f(b, 'growth_gain_est'):.3f} | "
          f"{abs(de - dt) / abs(dt) * 100:.1f} |")
if len(est) > 1:
    sd = statistics.stdev(est)
    print(f"\nsd of the estimated change over seeds {' '.join(seeds)}: {sd:.2e} ohm m2 = {sd / abs(dt) * 100:.1f} % "
          f"of the true change")
