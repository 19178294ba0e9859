#!/usr/bin/env bash
# A UDDS-like drive cycle as a cycler export (1 s samples, charge-positive current, the
# cycler's own column names): micro-trips that accelerate, cruise, brake with regeneration
# and stop, after a 30 s rest. The same generator as the drive cycle of
# tests/cli/diagnose_bad_input_test.sh, with its length and current scale as options. The
# voltage column is a placeholder: `bmssim simulate --protocol csv:FILE` drives the truth
# with the current and writes the voltage.
#
# Usage: scripts/drive-cycle.sh OUT.csv [DURATION_S=10000] [SCALE=0.18] [REGEN=1.0] [SEED=7]
# SCALE multiplies every current (1 is the test's shape, peaks near 30 A); REGEN is the braking
# current's share of the test's. The defaults make the record of docs/results/diagnosis.md
# "Drive cycles and speed": 10 000 s, discharge peaks 5.9 A, regeneration peaks 5.6 A, 26 % of
# the time at rest, 1.6 Ah net discharge (the paper cell holds 2.3 Ah):
#   scripts/drive-cycle.sh udds10k.csv
set -euo pipefail
[ "$#" -ge 1 ] || { echo "usage: $0 OUT.csv [DURATION_S] [SCALE] [REGEN] [SEED]" >&2; exit 2; }
out=$1 duration=${2:-10000} scale=${3:-0.18} regen=${4:-1.0} seed=${5:-7}
awk -v dur="$duration" -v s="$scale" -v rg="$regen" -v seed="$seed" 'BEGIN {
  srand(seed); print "Time (s),Current (A),Voltage (V)"; t = 0
  for (k = 0; k < 30; k++) printf "%d,0,3.3\n", t++
  while (t < dur) {
    vmax = 8 + 17 * rand(); acc = 0.8 + 0.7 * rand(); v = 0
    while (v < vmax && t < dur) { v += acc; if (v > vmax) v = vmax; printf "%d,%.4f,3.3\n", t++, -s * (0.9 * v * acc + 0.5) }
    n = 10 + int(40 * rand()); for (k = 0; k < n && t < dur; k++) printf "%d,%.4f,3.3\n", t++, -s * (0.025 * v * v + 0.8)
    while (v > 0 && t < dur) { d = 0.8 + 0.6 * rand(); v -= d; if (v < 0) v = 0; printf "%d,%.4f,3.3\n", t++, s * rg * v * d }
    n = 5 + int(30 * rand()); for (k = 0; k < n && t < dur; k++) printf "%d,0,3.3\n", t++
  } }' > "$out.tmp"
mv "$out.tmp" "$out"
