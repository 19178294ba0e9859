#!/usr/bin/env bash
# An option that the chosen settings do not use exits 2 naming it (the contract): for each
# profile of `bmssim estimate`, every option it does not use, alone, exits 2 with one line that
# names the option, before the data is read, and leaves no summary.json; the options it uses
# run. bms-firmware and `bmssim hil` refuse --h where the profile takes H from the model.
#   estimate_options_test.sh BMSSIM [BMS_FIRMWARE]
set -uo pipefail
BMSSIM="$1"; FW="${2:-}"
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
source "$(dirname "$0")/input_error_check.sh"
cd "$WORK" || exit 1
# A short truth.csv: 60 s of 2.5 A CC charge (enough for the estimator to run, not to learn).
{ echo "t_s,cycle,mode,current_a,voltage_v,current_meas_a,voltage_meas_v,r_film_ohm_m2"
  awk 'BEGIN { for (k = 0; k < 300; k++) printf "%.1f,1,cc_charge,-2.5,%.6f,-2.5,%.6f,0.003391\n", 0.2 * k, 3.3 + 1e-5 * k, 3.3 + 1e-5 * k }'
} > short.csv

# refused PROFILE OPTION [VALUE]: exit 2, one line naming --OPTION, no output.
refused() {
  local profile=$1 opt=$2; shift 2
  check_input_error "$profile-$opt" "--$opt\\b.*not used by --settings $profile" "$WORK/o" -- \
    "$BMSSIM" estimate --data missing.csv --settings "$profile" "--$opt" "$@" --quiet --out "$WORK/o"
}
# accepted PROFILE ARGS...: the run writes its summary.json.
accepted() {
  local profile=$1; shift
  rm -rf "$WORK/a"
  if "$BMSSIM" estimate --data short.csv --settings "$profile" "$@" --quiet --out "$WORK/a" 2> "$WORK/err_acc" &&
     [ -s "$WORK/a/summary.json" ]; then pass "$profile accepts $*"
  else fail "$profile accepts $*" "$(head -1 "$WORK/err_acc")"; fi
}

# --settings best: the eleven the review found, and the rest only RCSI reads.
for o in "nc 2" "eta 1" "lambda 0.99" "p0 1e-3" "p0-y0 1e-3" "theta0 0,0" "h 0.02" "calibrate-bias" "average" \
         "propagate-growth" "growth-scale 2" "r-film-init 0.004" "reference-after-resyncs 2"; do
  # shellcheck disable=SC2086
  refused best $o
done
# --settings paper: no observer, no bias calibration, no propagation, no identifier.
for o in "no-start-resync" "resync-window 5" "resync-current 0.2" "reference-after-resyncs 2" "growth-scale 2" \
         "no-inventory" "model-bias-ohm 0" "relinearise 1" "inventory-error-pct 1"; do
  # shellcheck disable=SC2086
  refused paper $o
done
# The stated spread is the identifier's sd: refused where RCSI learns.
for p in paper nominal-growth; do
  for o in "spread-anode-i0 0.1" "spread-cathode-i0 0.1" "spread-transport 0.1" "spread-area 0.01"; do
    # shellcheck disable=SC2086
    refused "$p" $o
  done
done
# A relative 1-sigma outside [0, 0.9] exits 2 naming the option.
for o in "spread-anode-i0 0.95" "spread-transport -0.1"; do
  read -r opt val <<< "$o"
  check_input_error "best-$opt-range" "--$opt" "$WORK/o" -- \
    "$BMSSIM" estimate --data short.csv --settings best "--$opt" "$val" --quiet --out "$WORK/o"
done
accepted best --spread-anode-i0 0.17 --spread-cathode-i0 0.16 --spread-transport 0.12 --spread-area 0.02
python3 - "$WORK/a/summary.json" <<'PY' && pass "summary records the stated spread" || fail "stated spread" "see above"
import json, sys
s = json.load(open(sys.argv[1]))["options"]["stated_spread_rel"]
assert s == {"anode_i0": 0.17, "cathode_i0": 0.16, "transport": 0.12, "area": 0.02}, s
PY
# A front end's stated accuracy (the voltage sensor's offset: the film's sd; the current sensor's
# gain: the capacity's sd): refused where RCSI learns, out of range exit 2 naming the option,
# recorded in summary.json.
stated_accuracy() {  # OPTION ABOVE_MAX VALUE SUMMARY_KEY
  local opt=$1 above=$2 val=$3 key=$4 bad
  for p in paper nominal-growth; do refused "$p" "$opt" 0.3; done
  for bad in -0.1 "$above"; do
    check_input_error "best-$opt-range-$bad" "--$opt" "$WORK/o" -- \
      "$BMSSIM" estimate --data short.csv --settings best "--$opt" "$bad" --quiet --out "$WORK/o"
  done
  accepted best "--$opt" "$val"
  python3 - "$WORK/a/summary.json" "$key" "$val" <<'PY' && pass "summary records $key" || fail "$key" "see above"
import json, sys
s = json.load(open(sys.argv[1]))["options"][sys.argv[2]]
assert abs(s - float(sys.argv[3])) < 1e-12, s
PY
}
stated_accuracy voltage-offset-sd-mv 11 0.2887 voltage_offset_sd_mv
# The initial film's stated tolerance is the prior's sd wherever the prior is reported: refused
# where RCSI learns; out of range exit 2 naming it; recorded in summary.json.
for p in paper nominal-growth; do refused "$p" film-initial-sd 0.1155; done
for bad in -0.1 0.95; do
  check_input_error "best-film-initial-sd-range-$bad" "--film-initial-sd" "$WORK/o" -- \
    "$BMSSIM" estimate --data short.csv --settings best --spread-anode-i0 0.17 --film-initial-sd "$bad" --quiet --out "$WORK/o"
done
accepted best --film-initial-sd 0.1155
accepted best --spread-anode-i0 0.17 --film-initial-sd 0.1155
python3 - "$WORK/a/summary.json" <<'PY' && pass "summary records the initial film's tolerance" || fail "film tolerance" "see above"
import json, sys
o = json.load(open(sys.argv[1]))["options"]
assert o["stated_film_initial_sd_rel"] == 0.1155 and o["stated_spread_rel"]["anode_i0"] == 0.17, o
PY
stated_accuracy current-gain-sd-pct 6 0.2887 current_gain_sd_pct
# --settings nominal-growth: H from the model, no identifier.
for o in "h 0.02" "no-inventory" "model-bias-ohm 0" "relinearise 1"; do
  # shellcheck disable=SC2086
  refused nominal-growth $o
done
# The full model has no observer: its options are refused there.
check_input_error full-resync-window "--resync-window.*not used" "$WORK/o" -- \
  "$BMSSIM" estimate --data missing.csv --model full --resync-window 5 --quiet --out "$WORK/o"
check_input_error reduced-points "--points.*not used" "$WORK/o" -- \
  "$BMSSIM" estimate --data missing.csv --points 10 --quiet --out "$WORK/o"
check_input_error custom "--settings must be" "$WORK/o" -- \
  "$BMSSIM" estimate --data missing.csv --settings custom --quiet --out "$WORK/o"

accepted best --no-inventory --model-bias-ohm 0 --relinearise 1 --warmup 0 --resync-window 5
accepted paper --p0 1e-3 --h 0.02 --nc 2 --theta0 1,0,0,0 --calibrate-bias --resync --resync-window 5
accepted nominal-growth --growth-scale 2 --p0 1e-6 --reference-after-resyncs 2
accepted paper --h-from-model --propagate-growth --growth-scale 0.5
# what ran is what summary.json says: the paper's p0 under paper, the given one when given.
python3 - "$WORK/a/summary.json" <<'PY' && pass "summary options are what ran" || fail "summary options" "see above"
import json, sys
o = json.load(open(sys.argv[1]))["options"]
assert o["settings"] == "paper" and o["h_from_model"] is True and "h" not in o, o
assert o["propagate_growth"] is True and "p0" in o and "learn_inventory" not in o, o
PY

# The noise bound is a score of the best profile's unknowns: a noise that is no standard deviation
# or another profile exits 2 naming it, before the data is read; the best profile writes the
# bound (crlb) beside its scores, and a run without the option writes none.
for bad in 0 -0.2 nan; do
  check_input_error "bound-noise-$bad" "--bound-noise-v-mv must be" "$WORK/o" -- \
    "$BMSSIM" estimate --data missing.csv --bound-noise-v-mv "$bad" --quiet --out "$WORK/o"
done
check_input_error bound-noise-paper "--bound-noise-v-mv.*--settings best" "$WORK/o" -- \
  "$BMSSIM" estimate --data missing.csv --settings paper --bound-noise-v-mv 0.2 --quiet --out "$WORK/o"
accepted best --bound-noise-v-mv 0.2
python3 - "$WORK/a/summary.json" <<'PY' && pass "summary has the bound" || fail "bound in summary" "see above"
import json, sys
c = json.load(open(sys.argv[1]))["crlb"]
assert c["noise_v_mv"] == 0.2 and c["valid"] is False and c["growth_sd_pct"] is None, c  # 60 s: no learning
PY
accepted best
python3 -c 'import json,sys; assert "crlb" not in json.load(open(sys.argv[1]))' "$WORK/a/summary.json" &&
  pass "no bound unless asked" || fail "no bound unless asked" "crlb written"

# A value out of an option's range is a parse error: still one line, naming the option.
check_input_error range-relinearise "--relinearise.*not in range.*estimate --help" "$WORK/o" -- \
  "$BMSSIM" estimate --data short.csv --relinearise 5 --quiet --out "$WORK/o"

if [ -n "$FW" ]; then
  for p in best nominal-growth; do
    check_input_error "firmware-$p-h" "--h\\b.*not used by --settings $p" "$WORK/o" -- \
      "$FW" --can vcan0 --lockstep --settings "$p" --h 0.02
  done
  check_input_error firmware-settings "--settings must be" "$WORK/o" -- \
    "$FW" --can vcan0 --lockstep --settings custom
  check_input_error hil-best-h "--h\\b.*not used by --settings best" "$WORK/o" -- \
    "$BMSSIM" hil --bus vcan0 --settings best --h 0.02 --quiet --out "$WORK/o"
fi
echo "estimate options: $PASSED passed, $FAILED failed"
[ "$FAILED" -eq 0 ]
