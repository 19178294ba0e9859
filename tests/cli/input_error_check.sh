# Sourced by the CLI bad-input tests: TAP-like counters and the one check they all make.
# Needs WORK (a scratch folder). After sourcing: pass NAME, fail NAME WHY,
# check_input_error NAME NEEDLE OUT_DIR -- COMMAND...  runs COMMAND and requires exit code
# exactly 2, exactly one line on stderr matching NEEDLE (extended regex, case-insensitive),
# and no summary.json in OUT_DIR (never a partial output that looks complete).
PASSED=0
FAILED=0
pass() { PASSED=$((PASSED + 1)); echo "ok - $1"; }
fail() { FAILED=$((FAILED + 1)); echo "not ok - $1: $2"; }

check_input_error() {
  local name=$1 needle=$2 out=$3; shift 4
  "$@" 2> "$WORK/err_$name" >/dev/null
  local rc=$?
  local first
  first=$(head -n 1 "$WORK/err_$name")
  if [ "$rc" -ne 2 ]; then fail "$name" "exit code $rc, expected 2 (stderr: $first)"; return; fi
  if [ "$(wc -l < "$WORK/err_$name")" -ne 1 ]; then fail "$name" "stderr is not one line: $(cat "$WORK/err_$name")"; return; fi
  if ! grep -qiE -- "$needle" <<< "$first"; then fail "$name" "stderr '$first' does not match '$needle'"; return; fi
  if [ -e "$out/summary.json" ]; then fail "$name" "summary.json written for bad input"; return; fi
  pass "$name"
}
