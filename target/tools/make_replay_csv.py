#!/usr/bin/python3
"""Makes the replay data set of the target test application from a truth-model run.

    build/host/host_sim/bmssim simulate --cell paper --protocol cccv --cycles 1 \
        --noise-v-mv 0.02 --seed 1 --quiet --out out/target-cycle
    target/tools/make_replay_csv.py out/target-cycle/truth.csv target/data/paper_cccv_cycle1.csv.gz

Keeps what the firmware receives, at the resolution it receives it: the measured voltage and
current as the raw integers of the HOST_Measurement CAN frame (10 uV and 0.1 mA steps,
firmware/include/bms/fw/can/can_protocol.hpp, rounded half away from zero like its encoder). The
true mode and film resistance are kept for reports only (they are not put in the image).
The output is gzip-compressed with a fixed time stamp, so the same input gives the same bytes.
"""
import csv
import gzip
import io
import math
import sys

MODES = {"rest": 0, "cc_discharge": 1, "cv_discharge": 2, "cc_charge": 3, "cv_charge": 4}
V_STEP = 1e-5
I_STEP = 1e-4


def raw(value, step):
    scaled = value / step
    return int(math.floor(scaled + 0.5)) if scaled >= 0.0 else int(math.ceil(scaled - 0.5))


def main(argv):
    if len(argv) != 3:
        print(__doc__, file=sys.stderr)
        return 2
    src, dst = argv[1], argv[2]
    out = io.StringIO()
    out.write("# Replay data of target/: paper cell, one CCCV cycle of the truth model, one row per\n")
    out.write("# 0.2 s tick. Made by target/tools/make_replay_csv.py from bmssim simulate --cell paper\n")
    out.write("# --protocol cccv --cycles 1 --noise-v-mv 0.02 --seed 1 (see docs/results/target.md).\n")
    out.write("# voltage_10uv, current_100ua: measured voltage and current as raw HOST_Measurement values\n")
    out.write("# (10 uV, 0.1 mA; current positive on discharge). mode (operating_mode.hpp numbering) and\n")
    out.write("# r_film_ohm_m2 are the truth, for reports only.\n")
    out.write("voltage_10uv,current_100ua,mode,r_film_ohm_m2\n")
    rows = 0
    last_t = None
    with open(src, newline="") as f:
        for r in csv.DictReader(f):
            t = float(r["t_s"])
            if last_t is not None and abs(t - last_t - 0.2) > 1e-6:
                print(f"make_replay_csv: {src}: samples are not 0.2 s apart at t = {t}", file=sys.stderr)
                return 2
            last_t = t
            out.write("%d,%d,%d,%.12g\n" % (raw(float(r["voltage_meas_v"]), V_STEP),
                                             raw(float(r["current_meas_a"]), I_STEP),
                                             MODES[r["mode"]], float(r["r_film_ohm_m2"])))
            rows += 1
    tmp = dst + ".tmp"
    with open(tmp, "wb") as f:
        with gzip.GzipFile(filename="", mode="wb", fileobj=f, mtime=0, compresslevel=9) as z:
            z.write(out.getvalue().encode())
    import os
    os.replace(tmp, dst)
    print(f"make_replay_csv: {rows} ticks -> {dst}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
