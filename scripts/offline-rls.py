#!/usr/bin/python3
"""Offline RLS (P(0) = 1e10, theta(0) = 0, no forgetting) of the first-order film subsystem
u(k) = M1 u(k-1) + N1 y0(k-1) on a recorded run, over its CC charges (the paper's figure 7).

usage: scripts/offline-rls.py FILE.csv [FILE.csv ...]
  truth.csv      u = r_film_ohm_m2, y0 = j_s_a_m3 (the truth's own signals)
  estimates.csv  u = r_film_est_ohm_m2 (RCSI's u_hat), y0 = j_side_a_m3 (the model's y0_hat),
                 ticks with RCSI learning only
Pairs that straddle two charges are skipped. Needs numpy (Debian python3-numpy).
"""
import csv
import sys

import numpy as np


def fit(u, y0, charge, p0=1e10):
    theta, p = np.zeros(2), np.eye(2) * p0
    for k in range(1, len(u)):
        if charge[k] != charge[k - 1]:
            continue
        phi = np.array([u[k - 1], y0[k - 1]])
        gain = p @ phi / (1.0 + phi @ p @ phi)
        theta = theta + gain * (u[k] - phi @ theta)
        p = p - np.outer(gain, phi @ p)
    return theta


for path in sys.argv[1:]:
    rows = list(csv.DictReader(open(path)))
    truth = "r_film_est_ohm_m2" not in rows[0]
    ucol, ycol = ("r_film_ohm_m2", "j_s_a_m3") if truth else ("r_film_est_ohm_m2", "j_side_a_m3")
    sel = [r for r in rows if r["mode"] == "cc_charge" and (truth or r["rcsi_active"] == "1")]
    theta = fit([float(r[ucol]) for r in sel], [float(r[ycol]) for r in sel], [r["cycle"] for r in sel])
    print(f"{path}: {len(sel)} samples, M1 = {theta[0]:.10f}, N1 = {theta[1]:.4e}")
