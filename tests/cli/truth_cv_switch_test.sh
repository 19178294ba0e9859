#!/usr/bin/env bash
# The truth's switch from current to voltage control survives a refactorisation whose stale pivot
# order makes KLU's solution NaN (dfn_solver.cpp, klu_solve_refactor_on_nan): the blind study's
# LCO truth of set 1, seed 10 on an 80-volume mesh at rtol 1e-8 (`study blind --cell lco
# --truth-points 80 --truth-rtol 1e-8 --list-cases`) failed in IDACalcIC at the start of cycle 2's
# CV charge. Two cycles of it must complete.
# Usage: truth_cv_switch_test.sh BMSSIM WORKDIR
set -euo pipefail
bmssim=$1
work=$2
rm -rf "$work"
mkdir -p "$work"
trap 'st=$?; [ "$st" -eq 0 ] && rm -rf "$work"; exit "$st"' EXIT  # kept only when the test fails
fail() { echo "FAIL: $*" >&2; exit 1; }

set +e
"$bmssim" simulate --cell lco --protocol cccv --cycles 2 --current-a 0.873 --cv-end-current-a 0.04365 \
  --points 80 --radial 80 --rtol 1e-08 --seed 10 --set r_film_initial_ohm_m2=0.00388775999299806 \
  --set film_growth_scale=1.7631972707360917 --set side_i0_scale=0.6092627247189328 \
  --set inventory_scale=1.0070887030883497 --quiet --out "$work/t" 2> "$work/err"
rc=$?
set -e
[[ $rc -eq 0 ]] || fail "simulate exited $rc: $(cat "$work/err")"
python3 - "$work/t/summary.json" <<'PY'
import json, sys
s = json.load(open(sys.argv[1]))
if s.get("complete") is not True or len(s.get("cycles", [])) != 2:
    sys.exit("FAIL: not two complete cycles: complete=%r cycles=%d" % (s.get("complete"), len(s.get("cycles", []))))
PY
echo "PASS: the LCO truth enters its CV charge on the fine mesh"
