#!/usr/bin/env bash
# Integration test: `bmssim simulate` must reject bad input cleanly.
#
# Usage: bad_input_test.sh BMSSIM SHARED_DIR
#
# For every bad-input case it asserts (docs: /work/shared/contract.md, "Conventions"):
#   - the exit code is exactly 2,
#   - the first line of stderr names the file and the field / column / line at fault,
#   - the --out folder holds no truth.csv and no summary.json afterwards.
# One positive control checks that a valid short run still exits 0 with the contract's
# columns. Prints `ok - NAME` / `not ok - NAME: why` per case and `N passed, M failed`;
# exits non-zero if any case failed. BAD_INPUT_TEST_VERBOSE=1 also prints each stderr.
set -u

if [ "$#" -ne 2 ]; then
  echo "usage: $0 BMSSIM SHARED_DIR" >&2
  exit 2
fi

abspath() { # absolute path of an existing file or folder, independent of the cwd
  if [ -d "$1" ]; then (cd "$1" && pwd -P); else
    printf '%s/%s\n' "$(cd "$(dirname "$1")" && pwd -P)" "$(basename "$1")"; fi
}

[ -x "$1" ] || { echo "bad_input_test: bmssim binary '$1' is not an executable file" >&2; exit 2; }
[ -d "$2" ] || { echo "bad_input_test: shared dir '$2' is not a folder" >&2; exit 2; }
BMSSIM=$(abspath "$1")
SHARED=$(abspath "$2")
DATA="$SHARED/data/aboutenergy-lfp18650"
BPX="$DATA/lfp_18650_cell_BPX.json"
CSV1C="$DATA/LFP_25degC_1C.csv"
PY=/usr/bin/python3
for f in "$BPX" "$CSV1C"; do
  [ -f "$f" ] || { echo "bad_input_test: missing shared data file '$f'" >&2; exit 2; }
done
[ -x "$PY" ] || { echo "bad_input_test: $PY not found" >&2; exit 2; }

WORK=$(mktemp -d "${TMPDIR:-/tmp}/bmssim_bad_input.XXXXXX") || exit 1
trap 'rm -rf "$WORK"' EXIT
cd "$WORK" || exit 1

# Per-invocation time limit: a bad input must be rejected long before this.
RUN_LIMIT_S=120
if command -v timeout >/dev/null 2>&1; then TIMEOUT=(timeout "$RUN_LIMIT_S"); else TIMEOUT=(); fi

PASSED=0
FAILED=0
pass() { PASSED=$((PASSED + 1)); echo "ok - $1"; }
fail() { FAILED=$((FAILED + 1)); echo "not ok - $1: $2"; }

# expect_bad NAME NEEDLE... -- BMSSIM_ARGS...
#   Runs `bmssim simulate BMSSIM_ARGS... --out $WORK/out_NAME --quiet`.
#   A NEEDLE is either
#     f:TEXT  fixed text that must appear in stderr's first line (case-sensitive, e.g. a path),
#     w:TEXT  fixed text that must appear in stderr's first line (case-insensitive),
#     r:ERE   extended regex that must match stderr's first line (case-insensitive).
expect_bad() {
  local name=$1; shift
  local needles=()
  while [ "$#" -gt 0 ] && [ "$1" != "--" ]; do needles+=("$1"); shift; done
  [ "$#" -gt 0 ] && shift # the "--"
  local out="$WORK/out_$name" errf="$WORK/stderr_$name" rc
  "${TIMEOUT[@]}" "$BMSSIM" simulate "$@" --out "$out" --quiet >"$WORK/stdout_$name" 2>"$errf"
  rc=$?
  local first nlines why=()
  first=$(head -n 1 "$errf")
  nlines=$(grep -c '' "$errf")
  if [ "$rc" -ne 2 ]; then why+=("exit code $rc, expected 2"); fi
  if [ -z "$first" ]; then
    why+=("stderr's first line is empty")
  else
    local n kind text ok
    for n in "${needles[@]}"; do
      kind=${n%%:*}; text=${n#*:}; ok=1
      case $kind in
        f) grep -qF -- "$text" <<<"$first" || ok=0 ;;
        w) grep -qiF -- "$text" <<<"$first" || ok=0 ;;
        r) grep -qiE -- "$text" <<<"$first" || ok=0 ;;
        *) echo "bad_input_test: bad needle '$n'" >&2; exit 2 ;;
      esac
      if [ "$ok" -eq 0 ]; then
        if [ "$kind" = r ]; then why+=("stderr's first line does not match /$text/")
        else why+=("stderr's first line does not name '$text'"); fi
      fi
    done
  fi
  [ -e "$out/truth.csv" ] && why+=("$out/truth.csv was written")
  [ -e "$out/summary.json" ] && why+=("$out/summary.json was written")
  if [ "${#why[@]}" -eq 0 ]; then
    pass "$name"
    [ "$nlines" -gt 1 ] && echo "# note: $name: stderr has $nlines lines (first line is checked)"
    [ "${BAD_INPUT_TEST_VERBOSE:-0}" = 1 ] && echo "#   stderr: $first"
  else
    local msg
    msg=$(IFS=';'; echo "${why[*]}")
    fail "$name" "$msg"
    echo "#   stderr ($nlines lines):"
    sed -n '1,5s/^/#     /p' "$errf"
  fi
  return 0
}

# --- inputs ------------------------------------------------------------------------------

# bpx_edit OUT PYTHON_STATEMENT: load the shared BPX file as `d`, run the statement, write OUT.
bpx_edit() {
  "$PY" - "$BPX" "$1" "$2" <<'PYEOF' || { echo "bad_input_test: could not write $2" >&2; exit 1; }
import json, sys
src, stmt, out = sys.argv[1], sys.argv[2], sys.argv[3]
with open(src) as f:
    d = json.load(f)
p = d["Parameterisation"]
exec(stmt)
with open(out, "w") as f:
    json.dump(d, f, indent=4)
PYEOF
}

B_MISSING="$WORK/missing_key.bpx.json"
B_BADEXPR="$WORK/bad_ocp_expression.bpx.json"
B_RANGE="$WORK/negative_thickness.bpx.json"
B_NOTJSON="$WORK/not_json.bpx.json"
B_DIFFUSIVITY="$WORK/diffusivity_1e10.bpx.json"
B_THICK="$WORK/thickness_1e10.bpx.json"
bpx_edit 'del p["Negative electrode"]["Particle radius [m]"]' "$B_MISSING"
bpx_edit 'p["Positive electrode"]["OCP [V]"] = "3.4 + * x"' "$B_BADEXPR"
bpx_edit 'p["Negative electrode"]["Thickness [m]"] = -1e-5' "$B_RANGE"
# A solid diffusivity of 1e10 m2/s made the solver crawl forever; 1e10 m thick failed in it.
bpx_edit 'p["Negative electrode"]["Diffusivity [m2.s-1]"] = 1e10' "$B_DIFFUSIVITY"
bpx_edit 'p["Separator"]["Thickness [m]"] = 1e10' "$B_THICK"
printf 'This is not JSON at all.\nTime [s],I[A],U[V]\n0,1,3.3\n' >"$B_NOTJSON"

# About:Energy format, 1 s steps, 20 data rows (file lines 2..21): line L holds t = L - 2.
# ae_csv OUT [awk program applied to the data rows]
ae_csv() {
  local out=$1 prog=${2:-'{print}'}
  awk 'BEGIN { print "Time [s],I[A],U[V]"
               for (i = 0; i < 20; i++) printf "%d,-2.0,%.3f\n", i, 3.40 - 0.001 * i }' |
    awk -F, -v OFS=, "NR == 1 {print; next} $prog" >"$out"
}
C_NONMONO="$WORK/non_monotonic.csv"
C_GAP="$WORK/gap.csv"
C_NAN="$WORK/nan_current.csv"
C_NOCOL="$WORK/missing_column.csv"
# line 11 has t = 9 and line 12 has t = 10: swap them, so time goes back at line 12.
ae_csv "$C_NONMONO" 'NR == 11 {$1 = 10} NR == 12 {$1 = 9} {print}'
# from line 12 on, time jumps by 10000 s: one step of 10000 s (line 11 -> line 12).
ae_csv "$C_GAP" 'NR >= 12 {$1 = $1 + 9999} {print}'
# line 8: current is NaN.
ae_csv "$C_NAN" 'NR == 8 {$2 = "nan"} {print}'
# no U[V] column at all.
ae_csv "$WORK/full.csv"
awk -F, -v OFS=, '{print $1, $2}' "$WORK/full.csv" >"$C_NOCOL"

C_SHORT="$WORK/short_1C.csv"
head -n 30 "$CSV1C" >"$C_SHORT"

# A line number L named either as "line L" / "line: L" / "row L" or as "FILE:L".
line_re() { printf '((line|row)[^0-9a-z]{0,3}%s([^0-9]|$))|(%s:%s([^0-9]|$))' "$2" "$(printf '%s' "$1" | sed 's/[]\\.*^$+?(){}|[]/\\&/g')" "$2"; }

# --- cases -------------------------------------------------------------------------------

P1C="csv:$CSV1C"
expect_bad bpx_missing_key      "f:$B_MISSING" "w:Particle radius" -- --cell "$B_MISSING" --protocol "$P1C"
expect_bad bpx_bad_ocp_expr     "f:$B_BADEXPR" "w:OCP"             -- --cell "$B_BADEXPR" --protocol "$P1C"
expect_bad bpx_negative_thickness "f:$B_RANGE" "w:Thickness"       -- --cell "$B_RANGE"   --protocol "$P1C"
expect_bad bpx_diffusivity_1e10 "f:$B_DIFFUSIVITY" "w:Diffusivity" -- --cell "$B_DIFFUSIVITY" --protocol "$P1C"
expect_bad bpx_thickness_1e10   "f:$B_THICK" "w:Separator.Thickness" -- --cell "$B_THICK" --protocol "$P1C"
expect_bad bpx_not_json         "f:$B_NOTJSON"                     -- --cell "$B_NOTJSON" --protocol "$P1C"

expect_bad csv_non_monotonic_time "f:$C_NONMONO" "r:$(line_re "$C_NONMONO" 12)" -- --cell aboutenergy --protocol "csv:$C_NONMONO"
expect_bad csv_time_gap           "f:$C_GAP"     "r:$(line_re "$C_GAP" 12)"     -- --cell aboutenergy --protocol "csv:$C_GAP"
expect_bad csv_nan_current        "f:$C_NAN"     "r:$(line_re "$C_NAN" 8)" 'r:I\[A\]|column[^0-9a-z]{0,3}2([^0-9]|$)' \
                                                                                -- --cell aboutenergy --protocol "csv:$C_NAN"
expect_bad csv_missing_column     "f:$C_NOCOL"   "w:U[V]"                       -- --cell aboutenergy --protocol "csv:$C_NOCOL"

expect_bad inverted_voltage_limits 'r:v[-_]?min|v[-_]?max|limit' -- --cell paper --protocol cccv --v-min 3.7 --v-max 2.0

expect_bad unknown_cell          "w:nosuchcell"         -- --cell nosuchcell --protocol cccv
expect_bad unknown_effect        "w:foo"                -- --cell paper --protocol cccv --effect foo=1
expect_bad malformed_effect      "w:contact_resistance" -- --cell paper --protocol cccv --effect contact_resistance
expect_bad negative_dt           "w:dt"                 -- --cell paper --protocol cccv --dt -1
expect_bad negative_hysteresis   "w:hysteresis"         -- --cell paper --protocol cccv --effect hysteresis=-0.01
expect_bad huge_hysteresis       "w:hysteresis"         -- --cell paper --protocol cccv --effect hysteresis=2
expect_bad zero_thermal          "w:thermal"            -- --cell paper --protocol cccv --effect thermal=0
expect_bad nan_thermal           "w:thermal"            -- --cell paper --protocol cccv --effect thermal=nan
expect_bad negative_reactant_ea  "w:resistive_reactant_positive_ea" -- --cell paper --protocol cccv --effect resistive_reactant_positive_ea=-1
expect_bad huge_reactant_ea      "w:resistive_reactant_positive_ea" -- --cell paper --protocol cccv --effect resistive_reactant_positive_ea=3e5
expect_bad unknown_option        "w:frobnicate"         -- --cell paper --protocol cccv --frobnicate

MISSING_CSV="$WORK/no/such/dir/nonexistent.csv"
expect_bad missing_protocol_file "f:$MISSING_CSV" -- --cell aboutenergy --protocol "csv:$MISSING_CSV"

# --- positive control --------------------------------------------------------------------

positive_control() {
  local name=valid_short_run out="$WORK/out_valid" rc why=()
  "${TIMEOUT[@]}" "$BMSSIM" simulate --cell aboutenergy --protocol "csv:$C_SHORT" --out "$out" --quiet \
    >"$WORK/stdout_$name" 2>"$WORK/stderr_$name"
  rc=$?
  [ "$rc" -eq 0 ] || why+=("exit code $rc, expected 0")
  if [ -f "$out/truth.csv" ]; then
    local header col rows
    header=$(head -n 1 "$out/truth.csv" | tr -d '\r')
    for col in t_s cycle mode current_a voltage_v current_meas_a voltage_meas_v r_film_ohm_m2 \
               j_s_a_m3 li_loss_ah temperature_k; do
      grep -qE "(^|,)${col}(,|$)" <<<"$header" || why+=("truth.csv header lacks column $col")
    done
    rows=$(($(grep -c '' "$out/truth.csv") - 1))
    [ "$rows" -ge 2 ] || why+=("truth.csv has $rows data rows")
  else
    why+=("no truth.csv")
  fi
  if [ -f "$out/summary.json" ]; then
    "$PY" - "$out/summary.json" <<'PYEOF' || why+=("summary.json is not valid JSON with cycles, sim_s, wall_s")
import json, sys
d = json.load(open(sys.argv[1]))
assert isinstance(d.get("cycles"), list) and "sim_s" in d and "wall_s" in d
PYEOF
  else
    why+=("no summary.json")
  fi
  if [ "${#why[@]}" -eq 0 ]; then pass "$name"; else
    fail "$name" "$(IFS=';'; echo "${why[*]}")"
    sed -n '1,5s/^/#     /p' "$WORK/stderr_$name"
  fi
}
positive_control

echo "$PASSED passed, $FAILED failed"
[ "$FAILED" -eq 0 ]
