#!/usr/bin/env python3
"""Scores of scripts/any-cell-study.sh: film error (median over cycles 3-5 of each cycle's median
CC-charge error), growth_err_pct, capacity error and the learning-off ratio, per cell and seed.

Capacity (contract, `estimate`): the charge between the voltage limits at equilibrium from the
cell's lithium inventory and electrode capacities. Truth: the truth's mean stoichiometries;
estimate: the nominal inventory x (1 + the identified deviation) less the model's lithium loss.
Both through the cell's BPX OCP expressions (bisection), at the end of each cycle's CC charge."""
import csv, json, math, os, statistics, sys

F = 96485.33212
root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
files = {"aboutenergy": os.environ.get("BMS_SHARED_DIR", os.path.join(root, "..", "shared"))
         + "/data/aboutenergy-lfp18650/lfp_18650_cell_BPX.json",
         "lco": root + "/host_sim/cells/lco.bpx.json", "nmc": root + "/host_sim/cells/nmc.bpx.json"}


def cell_of(name):
    p = json.load(open(files[name]))["Parameterisation"]
    c = p["Cell"]
    area = c["Electrode area [m2]"] * c["Number of electrode pairs connected in parallel to make a cell"]
    out = {"vmin": c["Lower voltage cut-off [V]"], "vmax": c["Upper voltage cut-off [V]"]}
    for key, e in (("n", "Negative electrode"), ("p", "Positive electrode")):
        s = p[e]
        eps = s["Surface area per unit volume [m-1]"] * s["Particle radius [m]"] / 3
        out["Q" + key] = eps * s["Thickness [m]"] * area * s["Maximum concentration [mol.m-3]"]
        expr = s["OCP [V]"]
        out["U" + key] = (lambda ex: lambda x: eval(ex, {"exp": math.exp, "tanh": math.tanh, "log": math.log,
                                                         "sqrt": math.sqrt, "x": x}))(expr)
        out[key + "0"] = s["Maximum stoichiometry"] if key == "n" else s["Minimum stoichiometry"]
    return out


def capacity_ah(c, n_mol):
    def x_at(v):
        lo, hi = 1e-4, 1 - 1e-4
        f = lambda x: c["Up"]((n_mol - c["Qn"] * x) / c["Qp"]) - c["Un"](x) - v
        for _ in range(100):
            m = (lo + hi) / 2
            try:
                fm = f(m)
            except (OverflowError, ValueError):
                fm = float("inf")
            if fm < 0:
                lo = m
            else:
                hi = m
        return (lo + hi) / 2
    return c["Qn"] * (x_at(c["vmax"]) - x_at(c["vmin"])) * F / 3600


def capacity_errors(c, truth_csv, est_csv):
    truth = list(csv.DictReader(open(truth_csv)))
    est = list(csv.DictReader(open(est_csv)))
    nominal = c["Qn"] * c["n0"] + c["Qp"] * c["p0"]
    errs = {}
    for i, r in enumerate(est):
        if r["mode"] != "cc_charge" or (i + 1 < len(est) and est[i + 1]["mode"] == "cc_charge"):
            continue
        t = truth[i]
        n_true = c["Qn"] * float(t["stoich_neg"]) + c["Qp"] * float(t["stoich_pos"])
        n_est = nominal * (1 + float(r["inventory_deviation_est"])) - float(r["li_loss_ah"]) * 3600 / F
        q_true, q_est = capacity_ah(c, n_true), capacity_ah(c, n_est)
        errs[int(r["cycle"])] = abs(q_est - q_true) / q_true * 100
    return errs


def film_3_5(summary):
    return statistics.median(x["r_film_err_median_pct"] for x in summary["cycles"] if x["cycle"] >= 3)


def residual_mv(est_csv, constant_ohm, warmup_s=900.0):
    """The control run's CC-charge residual of cycles 3-5 past the warm-up (the ticks the
    identifier learns from): z, z less the constant design-time bias alone and z less the bias the
    identifier subtracts (model_bias_v: with the table), 10th / 50th / 90th percentile, mV."""
    raw, const, less = [], [], []
    start = None
    for r in csv.DictReader(open(est_csv)):
        if r["mode"] != "cc_charge":
            start = None
            continue
        t = float(r["t_s"])
        start = t if start is None else start
        if int(r["cycle"]) < 3 or t - start <= warmup_s:
            continue
        z = float(r["z_v"])
        raw.append(z * 1e3)
        const.append((z + constant_ohm * float(r["model_current_a"])) * 1e3)
        less.append((z - float(r["model_bias_v"])) * 1e3 if r.get("model_bias_v") else float("nan"))
    q = lambda v: [sorted(v)[int(p * (len(v) - 1) + 0.5)] for p in (0.1, 0.5, 0.9)]
    return q(raw), q(const), q(less)


out, cells = sys.argv[1], sys.argv[2:]
seeds = [int(s) for s in os.environ.get("SEEDS", "901 902 903").split()]
# Two capacities: the open-circuit capacity of the identified inventory alone (this script's
# bisection, no electrode-capacity scale), and the estimator's own capacity_est_ah as the contract
# scores it (summary.json capacity_err_pct: with the area scale the CV-end pins measure).
# growth bound: the Cramer-Rao bound of the growth growth_err_pct scores from the 0.2 mV noise alone
# (summary.json crlb.growth_sd_pct, `estimate --bound-noise-v-mv`; 1-sigma, % of the true growth).
print("| cell | seed | film error cycles 3-5, % | growth_err_pct | growth bound (noise, 1 sd), % | capacity error of the identified inventory (max, cycles 1-5), % | "
      "capacity_err_pct (contract; max |.|, cycles 1-5) | film error, learning off, % | off / on |")
print("|---|---|---|---|---|---|---|---|---|")
for cell in cells:
    c = cell_of(cell)
    for seed in seeds:
        run = f"{out}/{cell}-{seed}"
        on = json.load(open(run + "/est/summary.json"))
        off = json.load(open(run + "/off/summary.json"))
        cap = capacity_errors(c, run + "/truth/truth.csv", run + "/est/estimates.csv")
        f_on, f_off = film_3_5(on), film_3_5(off)
        contract = max(abs(x["capacity_err_pct"]) for x in on["cycles"])
        bound = (on.get("crlb") or {}).get("growth_sd_pct")
        bound_txt = "-" if bound is None else f"{bound:.1f}"
        print(f"| {cell} | {seed} | {f_on:.2f} | {on['growth_err_pct']:.1f} | {bound_txt} | {max(cap.values()):.3f} | "
              f"{contract:.3f} | {f_off:.2f} | {f_off / f_on:.2f} |")

print()
print("| cell | seed | control run's z | z less the constant bias | spread | z less the bias in use | spread |")
print("|---|---|---|---|---|---|---|")
fmt3 = lambda v: f"{v[0]:.2f} / {v[1]:.2f} / {v[2]:.2f}"
for cell in cells:
    for seed in seeds:
        run = f"{out}/{cell}-{seed}/off"
        constant = json.load(open(run + "/summary.json"))["options"]["model_bias_ohm"]
        raw, const, less = residual_mv(run + "/estimates.csv", constant)
        print(f"| {cell} | {seed} | {fmt3(raw)} | {fmt3(const)} | {const[2] - const[0]:.2f} | {fmt3(less)} | "
              f"{less[2] - less[0]:.2f} |")
print("(CC charges of cycles 3-5 past the 900 s warm-up, learning off; 10 / 50 / 90 %, mV)")
