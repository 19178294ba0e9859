#!/usr/bin/env bash
# Integration test: any cell with the firmware's model (bmssim estimate --cell X --model reduced,
# bmssim cell-config). A wrong or incomplete cell file is refused with exit 2 and one line naming
# the field, before any long work and without output; the templates generate a configuration
# whose summary states its table errors and design-time bias.
#
# Usage: any_cell_test.sh BMSSIM SHARED_DIR SOURCE_DIR
set -u
HERE=$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)
[ "$#" -eq 3 ] && [ -x "$1" ] && [ -d "$2" ] && [ -d "$3" ] || { echo "usage: $0 BMSSIM SHARED_DIR SOURCE_DIR" >&2; exit 2; }
BMSSIM=$(realpath "$1")
export BMS_SHARED_DIR
BMS_SHARED_DIR=$(realpath "$2")
SRC=$(realpath "$3")
WORK=$(mktemp -d "${TMPDIR:-/tmp}/bmssim_any_cell.XXXXXX") || exit 1
trap 'rm -rf "$WORK"' EXIT
cd "$WORK" || exit 1
# shellcheck source=input_error_check.sh
. "$HERE/input_error_check.sh"

# A short truth of the LCO template to estimate on (2 minutes of 1C discharge).
"$BMSSIM" simulate --cell lco --protocol "Discharge at 1C for 2 minutes" --points 8 --radial 8 --quiet \
  --out truth 2> err_truth || fail "lco_truth" "$(head -n 1 err_truth)"

python3 - "$SRC/host_sim/cells/lco.bpx.json" <<'PY'
import json, sys
good = json.load(open(sys.argv[1]))
missing = json.loads(json.dumps(good))
del missing["Parameterisation"]["Negative electrode"]["Particle radius [m]"]
json.dump(missing, open("missing.bpx.json", "w"))
bad_sei = json.loads(json.dumps(good))
bad_sei["Parameterisation"]["User-defined"]["SEI reaction exchange current density [A.m-2]"] = -4e-9
json.dump(bad_sei, open("bad_sei.bpx.json", "w"))
bad_ocp = json.loads(json.dumps(good))
bad_ocp["Parameterisation"]["Positive electrode"]["OCP [V]"] = "4.0 + 0.01 * log(0.98 - x)"
json.dump(bad_ocp, open("bad_ocp.bpx.json", "w"))
PY

for cmd in estimate cell-config; do
  extra=()
  [ "$cmd" = estimate ] && extra=(--data truth/truth.csv --model reduced)
  check_input_error "${cmd}_missing_field" "missing.bpx.json.*Negative electrode.Particle radius" "$WORK/out_$cmd" -- \
    "$BMSSIM" "$cmd" --cell missing.bpx.json "${extra[@]}" --out "$WORK/out_$cmd" --quiet
  check_input_error "${cmd}_bad_sei" "bad_sei.bpx.json.*User-defined.SEI reaction exchange current density" \
    "$WORK/out_$cmd" -- "$BMSSIM" "$cmd" --cell bad_sei.bpx.json "${extra[@]}" --out "$WORK/out_$cmd" --quiet
  check_input_error "${cmd}_ocp_not_finite_over_table" "bad_ocp.bpx.json.*Positive electrode.OCP" "$WORK/out_$cmd" -- \
    "$BMSSIM" "$cmd" --cell bad_ocp.bpx.json "${extra[@]}" --out "$WORK/out_$cmd" --quiet
done

# A template's configuration: header and summary with its errors and bias.
if "$BMSSIM" cell-config --cell lco --model-bias-ohm 1e-4 --out cfg --quiet 2> err_cfg &&
   python3 - <<'PY'
import json
s = json.load(open("cfg/summary.json"))
assert s["traits"] == "bms::fw::cells::LcoCellTraits", s
assert s["model_bias_ohm"] == 1e-4 and s["ocp_neg_max_err_v"] < 3e-5 and s["ocp_pos_max_err_v"] < 3e-5, s
h = open("cfg/lco_cell.hpp").read()
assert "struct LcoCellTraits" in h and "kRecordCrc32 = " + s["record_crc32"] in h and "kCellConfigSchema == 3" in h
PY
then pass "cell_config_lco"; else fail "cell_config_lco" "$(head -n 1 err_cfg)"; fi

# The reduced model on the template's data with a given bias: runs, and says so in its summary.
if "$BMSSIM" estimate --data truth/truth.csv --cell lco --model reduced --model-bias-ohm 1e-4 --quiet --out est 2> err_est &&
   [ -s est/estimates.csv ]; then pass "estimate_reduced_lco"; else fail "estimate_reduced_lco" "$(head -n 1 err_est)"; fi

echo "$PASSED passed, $FAILED failed"
[ "$FAILED" -eq 0 ]
