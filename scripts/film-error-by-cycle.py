#!/usr/bin/env python3
"""Signed median film-resistance error in CC charge, per cycle, of one or more estimate runs.

Reads the estimates.csv of `bmssim estimate` (rows whose detected mode is cc_charge and that
carry the true film resistance) and prints one markdown row per run:
    | label | cycle 1 | cycle 2 | ... |
with the signed median of 100 (R_est - R_true) / R_true. Used for the RCSI-with-an-
undeclared-effect table of docs/results/diagnosis.md (firmware-model.md reports the same
statistic).

usage: scripts/film-error-by-cycle.py LABEL=DIR/estimates.csv [LABEL=...]
"""
import csv
import statistics
import sys


def signed_medians(path):
    errs = {}
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            if r["mode"] != "cc_charge" or r["r_film_true_ohm_m2"] == "":
                continue
            true = float(r["r_film_true_ohm_m2"])
            if true == 0.0:
                continue
            errs.setdefault(int(r["cycle"]), []).append(100.0 * (float(r["r_film_est_ohm_m2"]) - true) / true)
    if not errs:
        raise ValueError("no cc_charge rows with a true film resistance")
    return {c: statistics.median(e) for c, e in sorted(errs.items())}


def main():
    if len(sys.argv) < 2 or any("=" not in a for a in sys.argv[1:]):
        sys.exit(__doc__.strip().splitlines()[-1])
    rows = []
    for arg in sys.argv[1:]:
        label, path = arg.split("=", 1)
        try:
            rows.append((label, signed_medians(path)))
        except (OSError, KeyError, ValueError) as e:
            sys.exit(f"film-error-by-cycle: {path}: {e}")
    cycles = sorted({c for _, m in rows for c in m})
    print("| run | " + " | ".join(f"cycle {c}" for c in cycles) + " |")
    print("|---|" + "---|" * len(cycles))
    for label, m in rows:
        print(f"| {label} | " + " | ".join(f"{m[c]:+.2f} %" if c in m else "-" for c in cycles) + " |")


if __name__ == "__main__":
    main()
