#!/usr/bin/env bash
# bmssim study blind, sets 4-6: each set exists and draws its truths as documented
# (docs/results/envelope.md): --list-cases prints the truth's simulate line per case, and those
# lines are checked against the stated ranges; the truth knobs they use do what they say; a set
# that does not exist exits 2. One 2-cycle study case runs end to end.
# Usage: blind_sets_test.sh BMSSIM WORKDIR
set -euo pipefail
bmssim=$1
work=$2
rm -rf "$work"
mkdir -p "$work"
trap 'st=$?; [ "$st" -eq 0 ] && rm -rf "$work"; exit "$st"' EXIT  # kept only when the test fails
fail() { echo "FAIL: $*" >&2; exit 1; }

# A set that does not exist, an unknown arm: exit 2 with a one-line message naming the option.
set +e
"$bmssim" study blind --sets 7 --list-cases > /dev/null 2> "$work/sets7.err"; rc=$?
set -e
[[ $rc -eq 2 ]] || fail "--sets 7 exited $rc (want 2)"
grep -q -- "--sets: '7'" "$work/sets7.err" || fail "--sets 7 message: $(cat "$work/sets7.err")"
set +e
"$bmssim" study blind --sets 4 --arms best,nonsense --list-cases > /dev/null 2> "$work/arms.err"; rc=$?
set -e
[[ $rc -eq 2 ]] || fail "--arms nonsense exited $rc (want 2)"
grep -q "nonsense" "$work/arms.err" || fail "--arms message: $(cat "$work/arms.err")"

"$bmssim" study blind --sets 1,4,5,6 --seeds 4 --cycles 2 --list-cases > "$work/cases.txt" 2> "$work/list.err" ||
  fail "--list-cases exited $?: $(cat "$work/list.err")"

python3 - "$work/cases.txt" <<'PY'
import re, shlex, sys
lines = [l.rstrip("\n") for l in open(sys.argv[1]) if l.strip()]
def fail(m):
    sys.exit("FAIL: " + m)
cases = {}
for l in lines:
    name, cmd = l.split(": ", 1)
    words = shlex.split(cmd)
    if words[:2] != ["bmssim", "simulate"]:
        fail("not a simulate line: " + l)
    opts = {"set": {}, "effect": {}}
    i = 2
    while i < len(words):
        w = words[i]
        if w in ("--set", "--effect"):
            k, v = words[i + 1].split("=")
            opts[w[2:]][k] = float(v)
            i += 2
        elif w.startswith("--"):
            opts[w[2:]] = words[i + 1]
            i += 2
        else:
            fail("stray word %r in %s" % (w, l))
    cases[name] = opts
def named(prefix):
    return {n: o for n, o in cases.items() if n.startswith(prefix)}
def within(v, lo, hi, what):
    if not lo <= v <= hi:
        fail("%s = %g outside [%g, %g]" % (what, v, lo, hi))
common = ["r_film_initial_ohm_m2", "film_growth_scale", "side_i0_scale", "inventory_scale"]

s1, s4, s5, s6 = named("set1-"), named("set4-"), named("set5-"), named("set6-")
# Sets 1, 4, 6: two noise cases per truth (0.2 mV, 5 mA); set 5: both at once, one case per truth.
if len(s1) != 8 or len(s4) != 8 or len(s6) != 8 or len(s5) != 4:
    fail("cases per set: %d %d %d %d" % (len(s1), len(s4), len(s5), len(s6)))
for n, o in s1.items():
    if sorted(o["set"]) != sorted(common) or o["effect"] or o["protocol"] != "cccv":
        fail("set 1 draws more than its four unknowns: " + n)
for n, o in s4.items():
    want = common + ["conductivity_scale", "electrolyte_diffusivity_scale", "diffusivity_scale_negative",
                     "diffusivity_scale_positive", "i0_scale_negative", "i0_scale_positive", "electrode_area_scale"]
    if sorted(o["set"]) != sorted(want) or list(o["effect"]) != ["particle_size"] or o["protocol"] != "cccv":
        fail("set 4 arguments: %s %s" % (n, o))
    for k in ("conductivity_scale", "electrolyte_diffusivity_scale", "diffusivity_scale_negative",
              "diffusivity_scale_positive"):
        within(o["set"][k], 0.8, 1.2, n + " " + k)
    for k in ("i0_scale_negative", "i0_scale_positive"):
        within(o["set"][k], 0.7, 1.3, n + " " + k)
    within(o["set"]["electrode_area_scale"], 0.97, 1.03, n + " electrode_area_scale")
    within(o["effect"]["particle_size"], 0.05, 0.3, n + " particle_size")
    within(o["set"]["inventory_scale"], 0.99, 1.01, n + " inventory_scale")
# The spread differs from truth to truth (drawn per seed, the same for both noises of a seed).
if len({o["set"]["i0_scale_negative"] for o in s4.values()}) != 4:
    fail("set 4: the anode's i0 is not drawn per seed")
for n, o in s5.items():
    if not n.endswith("-v0.2mV+i5mA") or o["noise-v-mv"] != "0.2" or o["noise-i-ma"] != "5":
        fail("set 5 is not both noises at once: " + n)
    if o["noise-t-k"] != "0.2" or sorted(o["set"]) != sorted(common):
        fail("set 5 arguments: %s %s" % (n, o))
    e = o["effect"]
    if sorted(e) != ["current_gain", "current_offset", "temperature_offset", "voltage_offset"]:
        fail("set 5 effects: %s" % e)
    within(e["current_offset"], -0.010, 0.010, n + " current_offset")
    within(e["current_gain"], -0.005, 0.005, n + " current_gain")
    within(e["voltage_offset"], -0.5e-3, 0.5e-3, n + " voltage_offset")
    if abs(e["temperature_offset"]) != 0.5:
        fail(n + " temperature_offset %g" % e["temperature_offset"])
protocols = set()
for n, o in s6.items():
    p = o["protocol"]
    m = re.fullmatch(r"Discharge at ([0-9.]+)C for ([0-9]+) minutes or until 2 V; Rest for ([0-9]+) minutes; "
                     r"Charge at ([0-9.]+)C until 3.6 V; Hold at 3.6 V until 125 mA; Rest for ([0-9]+) minutes", p)
    if not m or sorted(o["set"]) != sorted(common) or o["effect"]:
        fail("set 6 arguments: %s %s" % (n, o))
    d, dmin, r1, c, r2 = (float(x) for x in m.groups())
    within(d, 0.5, 1.0, n + " discharge C-rate")
    within(d * dmin / 60.0, 0.19, 0.91, n + " depth of discharge")
    within(r1, 5, 120, n + " first rest (min)")
    within(c, 0.3, 1.0, n + " charge C-rate")
    within(r2, 2, 60, n + " second rest (min)")
    protocols.add(p)
if len(protocols) != 4:
    fail("set 6: %d protocols for 4 seeds (drawn per seed)" % len(protocols))
print("blind sets: --list-cases ok (%d cases)" % len(cases))
PY

# The truth knobs the sets use: the electrode area scales the capacity, the voltage sensor's
# offset is added to voltage_meas_v only, a step that ends only on a voltage runs.
"$bmssim" simulate --cell paper --protocol "Rest for 1 minutes" --quiet --out "$work/nominal" ||
  fail "simulate nominal exited $?"
"$bmssim" simulate --cell paper --protocol "Rest for 1 minutes" --set electrode_area_scale=1.03 \
  --effect voltage_offset=0.0004 --quiet --out "$work/area" || fail "simulate area exited $?"
# 1 % more lithium: the anode is full below 3.6 V at rest; the capacity's upper end is then the
# full anode (bms/fw/model/open_circuit_capacity.hpp), finite, and estimate reads the file.
"$bmssim" simulate --cell paper --protocol "Rest for 1 minutes" --set inventory_scale=1.01 --quiet \
  --out "$work/rich" || fail "simulate inventory_scale=1.01 exited $?"
"$bmssim" simulate --cell paper --protocol "Discharge at 1C for 3 minutes; Charge at 1C until 3.6 V" --quiet \
  --out "$work/until" || fail "an experiment with a step ending only on a voltage exited $?"
set +e
"$bmssim" simulate --cell paper --protocol "Rest for 1 minutes" --effect voltage_offset=0.5 --quiet \
  --out "$work/bad" 2> "$work/bad.err"; rc=$?
set -e
[[ $rc -eq 2 ]] || fail "--effect voltage_offset=0.5 exited $rc (want 2)"
"$bmssim" simulate --list-params | grep -q "^electrode_area_scale " || fail "--list-params has no electrode_area_scale"

python3 - "$work" <<'PY'
import csv, json, sys
w = sys.argv[1]
def rows(d):
    return list(csv.DictReader(open(w + "/" + d + "/truth.csv")))
nom, area, until, rich = rows("nominal"), rows("area"), rows("until"), rows("rich")
rich_ratio = float(rich[-1]["capacity_ah"]) / float(nom[0]["capacity_ah"])
if not 1.003 < rich_ratio < 1.012:  # finite (NaN fails too), near the 1.0076 of the unit test
    sys.exit("FAIL: inventory_scale=1.01: capacity_ah %s (x%s of nominal)" % (rich[-1]["capacity_ah"], rich_ratio))
ratio = float(area[0]["capacity_ah"]) / float(nom[0]["capacity_ah"])
if abs(ratio - 1.03) > 1e-6:
    sys.exit("FAIL: electrode_area_scale=1.03 moved the capacity by %.6f" % ratio)
off = [float(r["voltage_meas_v"]) - float(r["voltage_v"]) for r in area]
if max(abs(x - 0.0004) for x in off) > 1e-12:
    sys.exit("FAIL: voltage_offset: voltage_meas_v - voltage_v = %g..%g" % (min(off), max(off)))
if json.load(open(w + "/area/summary.json"))["parameters"]["electrode_area_scale"] != 1.03:
    sys.exit("FAIL: summary.json does not record electrode_area_scale")
if until[-1]["mode"] != "cc_charge" or float(until[-1]["voltage_v"]) < 3.59:
    sys.exit("FAIL: 'Charge at 1C until 3.6 V' ended at %s V in %s" % (until[-1]["voltage_v"], until[-1]["mode"]))
print("blind sets: truth knobs ok (capacity x%.6f with the area)" % ratio)
PY

# One set-6 case end to end (2 cycles, the control arm only): the report's per-case table has it.
"$bmssim" study blind --sets 6 --seeds 1 --cycles 2 --arms best-no-learning --jobs 1 --out "$work/study" \
  2> "$work/study.log" || { cat "$work/study.log" >&2; fail "study exited $?"; }
python3 - "$work/study" <<'PY'
import json, sys
d = sys.argv[1]
s = json.load(open(d + "/summary.json"))
if s["truth_failures"] or len(s["cases"]) != 2:
    sys.exit("FAIL: cases %d, failures %s" % (len(s["cases"]), s["truth_failures"]))
for c in s["cases"]:
    a = c["arms"]
    if list(a) != ["best-no-learning"]:
        sys.exit("FAIL: arms run %s (asked best-no-learning only)" % list(a))
    if not c["truth"]["protocol"].startswith("Discharge at "):
        sys.exit("FAIL: the truth's protocol %r" % c["truth"]["protocol"])
    nl = a["best-no-learning"]
    # Both cycles have a CC charge to score; learning off: no learning tick in either.
    if len(nl["median_err_pct_by_cycle"]) != 2 or nl["learning_ticks_by_cycle"] != [0, 0]:
        sys.exit("FAIL: score %s / learning ticks %s" % (nl["median_err_pct_by_cycle"], nl["learning_ticks_by_cycle"]))
r = open(d + "/report.md").read()
if "set6-seed01-v0.2mV" not in r or "Per case (sets 4-6" not in r or "inside 2 sd" not in r:
    sys.exit("FAIL: report.md lacks the per-case table")
print("blind sets: set 6 study case ok")
PY
echo "blind sets: ok"
