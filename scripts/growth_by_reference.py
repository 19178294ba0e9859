#!/usr/bin/env python3
"""Diagnostics of growth_err_pct (docs/results/firmware-model.md, "Growth on the any-cell truths:
settling or the charge's end"), on estimates already written (no estimator is run):
  refs   growth_err_pct with the reference moved to the end of CC charge 1, 2, ..., n-1 (the
         contract fixes it at the first learning charge: this is the best a later start
         condition of the film's reference could do with these estimates);
  before the running film error of each CC charge at fixed times before the charge's end, and the
         growth_err_pct the first and last charge's values at that time would give (a proxy for a
         fit that stopped learning then: the estimate it held would also move the later charges).
Usage: growth_by_reference.py refs|before OUT_DIR CELL SEED...  (OUT_DIR/CELL-SEED/est/estimates.csv)"""
import csv, sys


def charges(path):
    rows = list(csv.DictReader(open(path)))
    segs, seg = [], []
    for i, r in enumerate(rows):
        if r["mode"] == "cc_charge":
            seg.append(r)
        if seg and (i + 1 == len(rows) or rows[i + 1]["mode"] != "cc_charge"):
            segs.append(seg)
            seg = []
    return segs


f = lambda r, k: float(r[k])


def growth(a_est, a_true, b_est, b_true):
    return abs((b_est - a_est) - (b_true - a_true)) / abs(b_true - a_true) * 100


def at_before(seg, seconds):
    t_end = f(seg[-1], "t_s")
    return min(seg, key=lambda r: abs(t_end - f(r, "t_s") - seconds))


what, out, cell, seeds = sys.argv[1], sys.argv[2], sys.argv[3], sys.argv[4:]
befores = [1800, 1200, 600, 480, 240, 120, 0]
if what == "refs":
    print("| cell | seed | growth_err_pct, reference at the end of CC charge 1 / 2 / ... / n-1 |")
    print("|---|---|---|")
else:
    print("| cell | seed | seconds before the charge's end | film error % of CC charge 1 / ... / n | growth_err_pct (first to last) |")
    print("|---|---|---|---|---|")
for s in seeds:
    segs = charges(f"{out}/{cell}-{s}/est/estimates.csv")
    if what == "refs":
        b = segs[-1][-1]
        g = [growth(f(a[-1], "r_film_est_ohm_m2"), f(a[-1], "r_film_true_ohm_m2"), f(b, "r_film_est_ohm_m2"),
                    f(b, "r_film_true_ohm_m2")) for a in segs[:-1]]
        print(f"| {cell} | {s} | " + " / ".join(f"{x:.0f}" for x in g) + " |")
        continue
    for sec in befores:
        rs = [at_before(seg, sec) for seg in segs]
        e = [(f(r, "r_film_est_ohm_m2") / f(r, "r_film_true_ohm_m2") - 1) * 100 for r in rs]
        g = growth(f(rs[0], "r_film_est_ohm_m2"), f(rs[0], "r_film_true_ohm_m2"), f(rs[-1], "r_film_est_ohm_m2"),
                   f(rs[-1], "r_film_true_ohm_m2"))
        print(f"| {cell} | {s} | {sec} | " + " / ".join(f"{x:+.2f}" for x in e) + f" | {g:.0f} |")
