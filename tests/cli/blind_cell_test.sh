#!/usr/bin/env bash
# bmssim study blind --cell: the blind study on a cell other than the paper's. --list-cases gives
# each truth's simulate line on that cell, at its 1C with a C/20 CV end, the initial film drawn
# around that cell's own; the baselines (paper cell only), another study mode and an unknown cell
# exit 2 with a line naming the option; --truth-points / --truth-rtol reach every truth's line;
# one 2-cycle LCO case runs end to end, its best arm on
# the cell's design-time bias and its bound written for both noises (the current noise through
# the LCO's own reduced model).
# Usage: blind_cell_test.sh BMSSIM WORKDIR
set -euo pipefail
bmssim=$1
work=$2
rm -rf "$work"
mkdir -p "$work"
trap 'st=$?; [ "$st" -eq 0 ] && rm -rf "$work"; exit "$st"' EXIT  # kept only when the test fails
fail() { echo "FAIL: $*" >&2; exit 1; }

refused() {  # NAME PATTERN ARGS...: exit 2, one line matching PATTERN
  local name=$1 pattern=$2 rc; shift 2
  set +e; "$bmssim" "$@" > /dev/null 2> "$work/$name.err"; rc=$?; set -e
  [[ $rc -eq 2 ]] || fail "$name exited $rc (want 2)"
  [[ $(wc -l < "$work/$name.err") -eq 1 ]] || fail "$name: not one line: $(cat "$work/$name.err")"
  grep -q -- "$pattern" "$work/$name.err" || fail "$name message: $(cat "$work/$name.err")"
}
refused ekf "--arms ekf" study blind --cell lco --arms best,ekf --list-cases
refused noise "--cell" study noise --cell lco --out "$work/noise"
refused nosuch "nosuch" study blind --cell nosuch --list-cases
refused points "--truth-points" study blind --cell lco --truth-points 5 --list-cases

# --truth-points / --truth-rtol: the truths' mesh and tolerance in every simulate line.
"$bmssim" study blind --cell lco --sets 1 --seeds 1 --truth-points 60 --truth-rtol 1e-8 --list-cases > "$work/fine.txt"
grep -c -- "--points 60 --radial 60 --rtol 1e-08 " "$work/fine.txt" | grep -qx 2 || fail "--truth-points not in the lines: $(cat "$work/fine.txt")"
# A printed line is one simulate accepts: with an unknown protocol swapped in it is refused for
# the protocol (after every option parsed), not for an option's syntax.
line=$(head -1 "$work/fine.txt"); line=${line#*: bmssim }; line=${line/--protocol cccv/--protocol nosuch}
set +e; eval "\"\$bmssim\" ${line/TRUTH/\"\$work/t\"}" > /dev/null 2> "$work/line.err"; rc=$?; set -e
[[ $rc -eq 2 ]] && grep -q "nosuch" "$work/line.err" ||
  fail "the printed simulate line is not accepted (exit $rc): $(cat "$work/line.err")"

"$bmssim" study blind --cell lco --sets 1 --seeds 3 --list-cases > "$work/cases.txt" 2> "$work/list.err" ||
  fail "--list-cases exited $?: $(cat "$work/list.err")"
"$bmssim" simulate --cell lco --list-params > "$work/params.txt"
python3 - "$work/cases.txt" "$work/params.txt" <<'PY'
import shlex, sys
lines = [l for l in open(sys.argv[1]) if l.strip()]
params = dict(l.split()[:2] for l in open(sys.argv[2]) if len(l.split()) >= 2)
if len(lines) != 6:
    sys.exit("FAIL: %d cases (want 3 seeds x 2 noises)" % len(lines))
for l in lines:
    w = shlex.split(l.split(": ", 1)[1])
    opt = lambda k: w[w.index(k) + 1]
    if opt("--cell") != "lco" or abs(float(opt("--current-a")) - 0.873) > 1e-9 or \
       abs(float(opt("--cv-end-current-a")) - 0.873 / 20) > 1e-9:
        sys.exit("FAIL: not the LCO at 1C, CV to C/20: " + l)
    sets = dict(w[i + 1].split("=") for i in range(len(w)) if w[i] == "--set")
    r0 = float(sets["r_film_initial_ohm_m2"]) / float(params["r_film_initial_ohm_m2"])
    if not 0.8 <= r0 <= 1.2 or not 0.99 <= float(sets["inventory_scale"]) <= 1.01:
        sys.exit("FAIL: set 1's draws off their ranges around the LCO's own film: " + l)
PY
echo "blind cell: list ok"

# One LCO truth, 2 cycles, the best arm and its control, end to end.
"$bmssim" study blind --cell lco --sets 1 --seeds 1 --cycles 2 --arms best,best-no-learning --jobs 2 \
  --out "$work/study" 2> "$work/study.log" || { cat "$work/study.log" >&2; fail "study exited $?"; }
python3 - "$work/study" <<'PY'
import json, sys
d = sys.argv[1]
s = json.load(open(d + "/summary.json"))
if s["options"]["cell"] != "lco" or s["truth_failures"] or len(s["cases"]) != 2:
    sys.exit("FAIL: options %s, failures %s, %d cases" % (s["options"], s["truth_failures"], len(s["cases"])))
for c in s["cases"]:
    if c["cell"] != "lco" or sorted(c["arms"]) != ["best", "best-no-learning"]:
        sys.exit("FAIL: case %s: cell %s, arms %s" % (c["case"], c["cell"], sorted(c["arms"])))
    if "--cell lco" not in c["commands"]["simulate"] or "--cell lco" not in c["commands"]["estimate"]:
        sys.exit("FAIL: commands %s" % c["commands"])
    best = c["arms"]["best"]
    if best["learning_ticks_by_cycle"][1] == 0 or not best["worst_err_pct_cycles_3_on"] < 100:
        sys.exit("FAIL: best did not learn on the LCO: %s" % best)
    if c["arms"]["best-no-learning"]["learning_ticks_by_cycle"] != [0, 0]:
        sys.exit("FAIL: the control learned")
    # The bound in both cases, the current noise folded in with the LCO's own dV/dI (tens of
    # milliohms: 5 mA adds well under a millivolt).
    sig = c.get("crlb", {}).get("sigma_v_effective_mv")
    v, i = c["noise"]["v_mv"], c["noise"]["i_ma"]
    if sig is None or (i == 0 and abs(sig - v) > 1e-12) or (i > 0 and not 0.0 < sig < 1.0):
        sys.exit("FAIL: the bound's effective noise in %s: %s" % (c["case"], sig))
r = open(d + "/report.md").read()
if "Cell: lco" not in r:
    sys.exit("FAIL: report.md does not name the cell")
if "Per case (sets 4-6" in r:
    sys.exit("FAIL: report.md has an empty per-case table for set 1")
print("blind cell: LCO study ok")
PY
echo "blind cell: ok"
