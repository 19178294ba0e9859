#!/usr/bin/python3
"""Table of a bus-fault sweep (tests/cli/hil_fault_sweep.sh): one row per scenario.

usage: hil_fault_table.py SWEEP_DIR NAME0 NAME1 ...   (SWEEP_DIR/s0 is the clean run)

Columns: faults injected (host side), detected by the firmware (its receive counters from
BMS_RxStats, and ticks with a fault bit in BMS_Status), ticks the firmware did not answer,
ticks from the end of a fault window until a tick without a fault bit, the median
film-resistance error over each CC charge and the error at its end (against the truth), the
estimate at the end of each CC charge against the clean run's, and the
largest deviation from the clean run's estimate over the CC charges.
"""
import csv
import json
import sys

STALE, DROPPED, V_RANGE, I_RANGE = 1, 2, 4, 8


def load(d):
    s = json.load(open(d + "/summary.json"))
    rows = list(csv.DictReader(open(d + "/estimates.csv")))
    truth_modes = [r["mode"] for r in csv.DictReader(open(d + "/truth.csv"))]
    return s, rows, truth_modes


def main():
    sweep, names = sys.argv[1], sys.argv[2:]
    clean_s, clean_rows, modes = load(sweep + "/s0")
    clean_end = [c["r_film_est_end_ohm_m2"] for c in clean_s["cycles"]]
    print("| fault | injected | detected: firmware counters | ticks with stale / range fault bit | ticks not answered "
          "| recovery after the window (ticks) | median film error in CC charge vs truth (%) | film error at CC end vs truth (%) "
          "| estimate at CC end vs clean run (%) | max deviation from clean run in CC charge (%) |")
    print("|---|---|---|---|---|---|---|---|---|---|")
    for i, name in enumerate(names):
        s, rows, _ = load(f"{sweep}/s{i}")
        hil = s["hil"]
        f = hil.get("faults", {})
        inj = {k: v for k, v in f.get("injected", {}).items() if v}
        cnt = f.get("firmware_counters", hil.get("firmware_counters", {}))
        det = {k: v for k, v in cnt.items() if v}
        status = [int(r["status"]) for r in rows]
        stale = sum(1 for x in status if x & STALE)
        rng = sum(1 for x in status if x & (V_RANGE | I_RANGE))
        rec = [w["recover_ticks_after_window"] for w in f.get("windows", [])]
        err = [c["r_film_err_end_pct"] for c in s["cycles"]]
        med = [c["r_film_err_median_pct"] for c in s["cycles"]]
        vs_clean = [100.0 * (c["r_film_est_end_ohm_m2"] - e) / e for c, e in zip(s["cycles"], clean_end)]
        dev = max((abs(float(a["r_film_est_ohm_m2"]) - float(b["r_film_est_ohm_m2"])) / float(b["r_film_est_ohm_m2"])
                   for a, b, m in zip(rows, clean_rows, modes) if m == "cc_charge"), default=0.0)
        fmt = lambda xs: ", ".join(f"{x:.3g}" for x in xs)
        print(f"| {name} | {', '.join(f'{k} {v}' for k, v in inj.items()) or '-'} "
              f"| {', '.join(f'{k} {v}' for k, v in det.items()) or '0'} | {stale} / {rng} "
              f"| {f.get('ticks_without_answer', 0)} | {fmt(rec) or '-'} | {fmt(med)} | {fmt(err)} | {fmt(vs_clean)} "
              f"| {100.0 * dev:.3g} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
