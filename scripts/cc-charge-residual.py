#!/usr/bin/env python3
"""Mean model residual in each CC charge, by time since the charge started, at the true film.

Reads an estimates.csv of `bmssim estimate` and removes the film part of the residual,
z_true = z - H (R_est - R_true) with H = dV/dR_film (0.88 V per ohm m2 for the paper cell at
2.5 A), so what is left is the main model's own voltage bias. Used for
docs/results/firmware-model.md ("Beyond the paper").

usage: scripts/cc-charge-residual.py ESTIMATES.csv [--h 0.88]
"""
import argparse
import csv
import sys

SEGMENTS_S = [(0, 2), (2, 60), (60, 600), (600, 1800), (1800, 3000), (3000, 3400), (3400, 4000)]


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("estimates")
    ap.add_argument("--h", type=float, default=0.88, help="dV/dR_film in V per ohm m2")
    a = ap.parse_args()
    charges = {}
    try:
        with open(a.estimates, newline="") as f:
            for r in csv.DictReader(f):
                if r["mode"] == "cc_charge":
                    charges.setdefault(int(r["cycle"]), []).append(r)
    except (OSError, KeyError, ValueError) as e:
        sys.exit(f"cc-charge-residual: {a.estimates}: {e}")
    if not charges:
        sys.exit(f"cc-charge-residual: {a.estimates}: no cc_charge rows")
    print("cycle | " + " | ".join(f"{lo}-{hi} s" for lo, hi in SEGMENTS_S) + "   (mean z at the true film, mV)")
    for cycle, rows in sorted(charges.items()):
        t0 = float(rows[0]["t_s"])
        sums = [[0.0, 0] for _ in SEGMENTS_S]
        for r in rows:
            t = float(r["t_s"]) - t0
            z = float(r["z_v"]) - a.h * (float(r["r_film_est_ohm_m2"]) - float(r["r_film_true_ohm_m2"]))
            for k, (lo, hi) in enumerate(SEGMENTS_S):
                if lo <= t < hi:
                    sums[k][0] += z
                    sums[k][1] += 1
        cells = [f"{1e3 * s / n:+.3f}" if n else "-" for s, n in sums]
        print(f"{cycle} | " + " | ".join(cells))


if __name__ == "__main__":
    main()
