#!/usr/bin/env python3
"""Grid fit of the truth model's particle-size spread (and optional self-heating) to the
About:Energy LFP 18650 discharges, fitted on one case, validated on the others
(docs/results/diagnosis.md, last section).

For every combination of --pos, --neg and --thermal values it runs
`bmssim simulate --cell aboutenergy --protocol csv:FILE --effect particle_size=P
--effect particle_size_negative=N [--effect thermal=H]` for each case and reports two RMSEs:
  reached: over the samples the model reaches (as `bmssim validate` and
           scripts/fit-measured-effects.py count them);
  full:    over every measured sample, a sample after the model's early stop counted at
           the model's last voltage (an early stop is an error, not a shorter test).
The fit minimises the full RMSE of --fit-case. One bmssim process at a time.

Usage: scripts/fit-particle-size.py --bmssim B --shared S --pos 0,0.3 --neg 0,0.3 [--thermal 0,0.1]
           [--scale "Positive electrode.Diffusivity [m2.s-1]=2"]
"""
import argparse
import importlib.util
import itertools
import math
import os
import sys

here = os.path.dirname(os.path.abspath(__file__))
spec = importlib.util.spec_from_file_location("fme", os.path.join(here, "fit-measured-effects.py"))
fme = importlib.util.module_from_spec(spec)
spec.loader.exec_module(fme)


def full_rmse(data, rows):
    t, _, v = fme.read_measured(data)
    model = {round(float(r["t_s"]), 6): float(r["voltage_v"]) for r in rows}
    last = float(rows[-1]["voltage_v"])
    sq = [((model.get(round(x, 6), last)) - y) ** 2 for x, y in zip(t, v)]
    return 1e3 * math.sqrt(sum(sq) / len(sq))


def evaluate(a, effects):
    out = {}
    for case in fme.CASES:
        try:
            data, rows = fme.simulate(a.bmssim, a.shared, case, effects, [], a.scale)
        except RuntimeError as e:
            out[case] = None
            print(f"  {' '.join(effects)} {case}: failed ({str(e).splitlines()[-1][:80]})", file=sys.stderr)
            continue
        reached, _, early = fme.compare(data, rows)
        out[case] = (reached, full_rmse(data, rows), early)
    return out


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--bmssim", required=True)
    p.add_argument("--shared", required=True)
    p.add_argument("--pos", default="0", help="particle_size values (cathode sigma), comma-separated")
    p.add_argument("--neg", default="0", help="particle_size_negative values (anode sigma)")
    p.add_argument("--thermal", default="0", help="thermal values (W/K; 0 = isothermal)")
    p.add_argument("--fit-case", default="1C", choices=list(fme.CASES))
    p.add_argument("--scale", action="append", default=[],
                   help="'SECTION.FIELD=FACTOR': run on a scaled copy of the BPX set (as fit-measured-effects.py)")
    a = p.parse_args()
    vals = lambda s: [float(x) for x in s.split(",")]
    print("| pos sigma | neg sigma | thermal W/K | " +
          " | ".join(f"{c} reached / full mV (early)" for c in fme.CASES) + " |")
    print("|---|---|---|" + "---|" * len(fme.CASES))
    best = None
    for ps, ns, h in itertools.product(vals(a.pos), vals(a.neg), vals(a.thermal)):
        effects = [f"particle_size={ps}", f"particle_size_negative={ns}"] + ([f"thermal={h}"] if h > 0 else [])
        res = evaluate(a, effects)
        cells = [("failed" if r is None else f"{r[0]:.2f} / {r[1]:.2f} ({r[2]})") for r in res.values()]
        print(f"| {ps} | {ns} | {h} | " + " | ".join(cells) + " |", flush=True)
        fit = res[a.fit_case]
        if fit is not None and (best is None or fit[1] < best[0]):
            best = (fit[1], (ps, ns, h), res)
    if best:
        ps, ns, h = best[1]
        print(f"\nbest on {a.fit_case} (full RMSE): particle_size={ps} particle_size_negative={ns} thermal={h}")
        for c, r in best[2].items():
            role = "fit" if c == a.fit_case else "validation"
            print(f"  {c} ({role}): " + ("failed" if r is None else f"reached {r[0]:.2f} mV, full {r[1]:.2f} mV, {r[2]} samples early"))


if __name__ == "__main__":
    main()
