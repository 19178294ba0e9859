#!/usr/bin/env bash
# The estimator on cells other than the paper's: for each cell, hidden truth (film-growth law x1.8,
# initial film +9 %, cyclable lithium -0.5 %), 0.2 mV voltage noise, 5 CCCV cycles at 1C within
# the cell's window (CV to C/20), seeds 901-903 (the training seeds; 904-906 held out); the firmware's
# reduced model built from the cell (--cell X --model reduced, best settings), and the control
# run (--no-learning). Prints one table row per cell and seed (scripts/any_cell_scores.py), and
# the control run's CC-charge residual less the design-time bias (10/50/90 %, cycles 3-5). The learning
# run also writes the noise's Cramer-Rao bound (--bound-noise-v-mv 0.2: the growth's floor).
# Usage: scripts/any-cell-study.sh [OUT_DIR] [CELLS...]   (default out/any-cell, aboutenergy lco)
# Environment: SEEDS="904 905 906" other seeds (the held-out ones: run once); ESTIMATE_ARGS="..."
# added to both estimates (e.g. --no-bias-table: the constant design-time bias alone);
# SIMULATE_ARGS="..." added to the truth's simulate (e.g. --points 80 --rtol 1e-8: a converged truth).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
out="${1:-$root/out/any-cell}"
shift || true
cells=("${@:-aboutenergy lco}")
read -r -a cells <<< "${cells[*]}"
bmssim="${BMSSIM:-$root/build/host/host_sim/bmssim}"  # BMSSIM: another build of it
[[ -x "$bmssim" ]] || { echo "any-cell-study: build first (./bms build host)" >&2; exit 1; }
seeds="${SEEDS:-901 902 903}"
read -r -a extra <<< "${ESTIMATE_ARGS:-}"
read -r -a sim_extra <<< "${SIMULATE_ARGS:-}"
for s in $seeds; do [[ "$s" =~ ^[0-9]+$ ]] || { echo "any-cell-study: SEEDS must be integers (got '$s')" >&2; exit 2; }; done
mkdir -p "$out"
for cell in "${cells[@]}"; do
  cap=$("$bmssim" simulate --cell "$cell" --list-params | python3 -c '
import sys
print({"aboutenergy": 2.0, "lco": 0.873, "nmc": 5.0, "paper": 2.3}[sys.argv[1]])' "$cell")
  cv_end=$(python3 -c "print($cap / 20)")
  r0=$(python3 -c "print(1.09 * 3.391e-3)")
  for seed in $seeds; do
    run="$out/$cell-$seed"
    "$bmssim" simulate --cell "$cell" --protocol cccv --cycles 5 --current-a "$cap" --cv-end-current-a "$cv_end" \
      --set film_growth_scale=1.8 --set "r_film_initial_ohm_m2=$r0" --set inventory_scale=0.995 \
      --noise-v-mv 0.2 --seed "$seed" ${sim_extra[@]+"${sim_extra[@]}"} --quiet --out "$run/truth"
    "$bmssim" estimate --data "$run/truth/truth.csv" --cell "$cell" --model reduced ${extra[@]+"${extra[@]}"} \
      --bound-noise-v-mv 0.2 --quiet --out "$run/est"
    "$bmssim" estimate --data "$run/truth/truth.csv" --cell "$cell" --model reduced --no-learning ${extra[@]+"${extra[@]}"} --quiet \
      --out "$run/off"
  done
done
SEEDS="$seeds" python3 "$root/scripts/any_cell_scores.py" "$out" "${cells[@]}"
