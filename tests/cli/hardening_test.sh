#!/usr/bin/env bash
# Hardening of the host tool: bad input exits 2 with one line naming it before any
# work; inputs that never end are refused; output folders are built whole (a failed run keeps
# its finished cycles under "complete": false, an interrupted one leaves nothing); simulate's
# memory does not grow with the run; an interrupted study stops its children.
# Usage: hardening_test.sh BMSSIM
set -u
BMSSIM="$1"
HERE="$(cd "$(dirname "$0")" && pwd)"
WORK="$(mktemp -d)"
trap 'rm -rf "$WORK"' EXIT
cd "$WORK" || exit 1
# shellcheck source=input_error_check.sh
. "$HERE/input_error_check.sh"
sim() { timeout 60 "$BMSSIM" simulate --quiet "$@"; }

# Bad values of every kind the issue lists: exit 2, one line naming the option, no output.
mkfifo fifo
i=0
while IFS='|' read -r needle args; do
  i=$((i + 1))
  # shellcheck disable=SC2086
  eval "check_input_error bad_$i \"\$needle\" out_bad -- sim $args --out out_bad"
done <<'CASES'
--dt|--dt 1e-9
--current-a|--current-a 1e6
--current-a|--current-a 23
--current-a|--current-a nan
contact_resistance|--effect contact_resistance=1e6
--v-min/--v-max|--v-min 3.30 --v-max 3.31
--cv-end-current-a|--cv-end-current-a 3
hysteresis|--effect hysteresis=0.49
thermal|--effect thermal=-1
step 1 'Discharge at 1C'|--protocol 'Discharge at 1C'
8.7C|--protocol 'Charge at 20 A until 3.6 V'
unknown step|--protocol 'Discharge at 1C until 2 V; Dance'
/dev/zero.*not a regular file|--protocol csv:/dev/zero
fifo.*not a regular file|--protocol csv:fifo
CASES

# A measured current far beyond the cell: exit 2 naming the file, sample and value.
printf 't_s,current_a,voltage_v\n0,1,3.3\n1,1e6,3.3\n2,1,3.3\n' > huge.csv
check_input_error huge_current "huge.csv: sample 2.*1e\+06 A" out_huge -- sim --protocol csv:huge.csv --out out_huge

# --out is checked before any work: an existing file, a foreign folder (1000 cycles requested).
echo keep > afile
mkdir foreign && echo mine > foreign/notes.txt
start=$(date +%s)
check_input_error out_is_file "--out 'afile': exists and is not a folder" afile -- sim --cycles 1000 --out afile
check_input_error out_foreign "--out 'foreign'.*no bmssim run wrote" foreign -- sim --cycles 1000 --out foreign
if [ "$(cat afile)" = keep ] && [ "$(cat foreign/notes.txt)" = mine ] && [ $(($(date +%s) - start)) -lt 10 ]; then
  pass out_checked_first
else fail out_checked_first "files touched or the check took $(($(date +%s) - start)) s"; fi

# Re-running into an earlier output replaces the folder whole (an estimate's files are gone
# after a simulate into the same folder); a file the user added there stops the run instead.
sim --cycles 1 --dt 10 --out first && "$BMSSIM" estimate --data first/truth.csv --quiet --out run 2>/dev/null &&
  sim --cycles 1 --dt 10 --out run
if [ ! -e run/estimates.csv ] && [ -f run/truth.csv ] && grep -q '"complete": true' run/summary.json; then pass rerun_replaces_whole
else fail rerun_replaces_whole "an earlier run's file kept or summary incomplete"; fi
touch run/stale.txt
check_input_error rerun_user_file "--out 'run'.*no bmssim run wrote" run_unused -- sim --cycles 1 --dt 10 --out run
[ -e run/stale.txt ] && rm run/stale.txt && pass rerun_user_file_kept || fail rerun_user_file_kept "run/stale.txt gone"

# A runtime failure (too much lithium: the anode fills in the CV charge) into that folder: exit 1,
# the samples so far kept under "complete": false with the reason; no staging folder left.
sim --cycles 3 --dt 10 --set inventory_scale=1.04 --out run 2> fail.err
rc=$?
if [ $rc -eq 1 ] && grep -q '"complete": false' run/summary.json && grep -q '"failure": "cycle 1, cv_charge' run/summary.json &&
   [ "$(wc -l < run/truth.csv)" -gt 100 ] && ! ls -d ./*.partial-* >/dev/null 2>&1 && grep -q 'complete": false' fail.err; then
  pass failure_keeps_finished_work
else fail failure_keeps_finished_work "exit $rc: $(head -c 300 fail.err)"; fi

# SIGTERM in the middle of a run: exit 143 and nothing left behind.
"$BMSSIM" simulate --quiet --cycles 50 --out term & pid=$!
sleep 2; kill -TERM $pid; wait $pid; rc=$?
if [ $rc -eq 143 ] && [ ! -e term ] && ! ls -d ./term.partial-* >/dev/null 2>&1; then pass sigterm_leaves_nothing
else fail sigterm_leaves_nothing "exit $rc, left: $(ls)"; fi

# Memory bounded by what is written: 4 cycles at 0.2 s hold no more than 1 cycle + 8 MB
# (each cycle's samples held in memory were about 5.7 MB).
rss_kb() { /usr/bin/time -f %M "$BMSSIM" simulate --quiet --cycles "$1" --out "rss$1" 2>&1 >/dev/null | tail -1; }
rss1=$(rss_kb 1); rss4=$(rss_kb 4)
if [ $((rss4 - rss1)) -lt 8192 ]; then pass "memory_bounded ($rss1 kB for 1 cycle, $rss4 kB for 4)"
else fail memory_bounded "$rss1 kB for 1 cycle, $rss4 kB for 4"; fi

# estimate: every sample rejected (voltage column in mV) is a failure, not an empty answer.
python3 - rss1/truth.csv mv.csv <<'PY'
import csv, sys
rows = list(csv.reader(open(sys.argv[1])))
k = rows[0].index("voltage_meas_v")
with open(sys.argv[2], "w", newline="") as f:
    w = csv.writer(f)
    w.writerow(rows[0])
    for r in rows[1:]:
        r[k] = str(float(r[k]) * 1000.0)
        w.writerow(r)
PY
timeout 120 "$BMSSIM" estimate --data mv.csv --quiet --out est_mv 2> est.err
rc=$?
if [ $rc -eq 1 ] && grep -q "rejected every one" est.err && [ ! -e est_mv ]; then pass estimate_all_rejected
else fail estimate_all_rejected "exit $rc: $(head -c 200 est.err)"; fi
check_input_error r_film_init_nan "--r-film-init" est_nan -- timeout 60 "$BMSSIM" estimate --data rss1/truth.csv --r-film-init nan --out est_nan
check_input_error r_film_init_neg "--r-film-init" est_neg -- timeout 60 "$BMSSIM" estimate --data rss1/truth.csv --r-film-init -1 --out est_neg

# SIGTERM to a study reaches its running cases (own process groups), which stop too.
"$BMSSIM" study noise --quick --jobs 2 --out study 2> study.err & pid=$!
sleep 4; kill -TERM $pid
timeout 30 tail --pid=$pid -f /dev/null; wait $pid; rc=$?
sleep 1
left=$(pgrep -f "$WORK/study" | wc -l)
if [ $rc -eq 143 ] && [ "$left" -eq 0 ]; then pass study_sigterm_stops_children
else fail study_sigterm_stops_children "exit $rc, $left processes left"; fi

# --collect of that interrupted study lists every planned step that did not complete (the
# steps of the cases it never started too), not only those of the cases it started.
"$BMSSIM" study noise --collect study > /dev/null 2> collect.err
rc=$?
counts=$(python3 - study <<'PY'
import json, os, sys
d = sys.argv[1]
plan = json.load(open(os.path.join(d, "plan.json")))
steps = [(c["name"], s["name"]) for c in plan["cases"] for s in c["steps"]]
done = sum(os.path.exists(os.path.join(d, "cases", c, s, "summary.json")) for c, s in steps)
started = sum(os.path.exists(os.path.join(d, "cases", c["name"], "case.json")) for c in plan["cases"])
listed = len(json.load(open(os.path.join(d, "summary.json")))["missing_steps"])
print(len(steps), done, listed, started, len(plan["cases"]))
PY
)
read -r planned done listed started ncases <<< "${counts:-0 0 -1 0 0}"
if [ $rc -eq 0 ] && [ "$listed" -eq $((planned - done)) ] && [ "$started" -lt "$ncases" ] &&
   grep -q "study: .* $listed missing steps" collect.err; then
  pass "study_collect_counts_missing ($listed missing of $planned planned steps, $done done; $started of $ncases cases started)"
else fail study_collect_counts_missing "exit $rc; listed $listed, planned $planned, done $done, started $started of $ncases: $(tail -n 1 collect.err)"; fi

# A signal to diagnose or estimate mid-run: they stop within a few seconds, exit 128 + N and
# leave no folder (no summary.json, no staging folder). diagnose also when the signal comes
# while it draws its plots (gnuplot, here a stand-in that waits, gets the signal too).
sim --cycles 1 --dt 1 --effect contact_resistance=0.002 --out sig_sim
# stopped NAME SIGNAL DELAY OUT -- COMMAND...: COMMAND in the background, SIGNAL after DELAY
# seconds (or, with DELAY "file:F", once F exists); then exit 128 + N within 10 s, nothing left.
stopped() {
  local name=$1 sig=$2 delay=$3 out=$4 pid t0 rc want; shift 5
  "$@" > /dev/null 2> "err_$name" & pid=$!
  if [ "${delay#file:}" != "$delay" ]; then
    for _ in $(seq 300); do [ -e "${delay#file:}" ] && break; sleep 0.1; done
  else sleep "$delay"; fi
  t0=$(date +%s); kill "-$sig" $pid
  timeout 30 tail --pid=$pid -f /dev/null; wait $pid; rc=$?
  want=$((128 + $(kill -l "$sig")))
  if [ $rc -eq $want ] && [ $(($(date +%s) - t0)) -le 10 ] && [ ! -e "$out" ] && ! ls -d "$out".partial-* >/dev/null 2>&1 &&
     grep -q "interrupted by signal.*unfinished output removed" "err_$name"; then
    pass "$name (exit $rc in $(($(date +%s) - t0)) s, nothing left)"
  else fail "$name" "exit $rc (want $want) after $(($(date +%s) - t0)) s; left: $(ls -d "$out"* 2>/dev/null); $(tail -n 1 "err_$name")"; fi
}
stopped diagnose_sigterm TERM 2 sig_d -- timeout 120 "$BMSSIM" diagnose --data sig_sim/truth.csv --cell paper --quiet --out sig_d
mkdir -p slowplot
printf '#!/bin/sh\n: > "%s/plotting"\nexec sleep 60\n' "$WORK" > slowplot/gnuplot && chmod +x slowplot/gnuplot
stopped diagnose_sigterm_plotting TERM "file:$WORK/plotting" sig_dp -- \
  env PATH="$WORK/slowplot:$PATH" timeout 120 "$BMSSIM" diagnose --data sig_sim/truth.csv --cell paper --candidates contact_resistance --quiet --out sig_dp
stopped estimate_sigterm TERM 1.5 sig_e -- timeout 120 "$BMSSIM" estimate --data sig_sim/truth.csv --model full --quiet --out sig_e
stopped estimate_sigint INT 1.5 sig_ei -- timeout 120 "$BMSSIM" estimate --data sig_sim/truth.csv --model full --quiet --out sig_ei

# A full disk (a 64 KiB tmpfs, mounted in a mount namespace of its own): exit 1, one line
# saying what happened and what to try, nothing left on the disk.
disk_full() {  # runs in the namespace: mount, run, list what is left
  mount -t tmpfs -o size=64k tmpfs small || exit 77
  "$@" > /dev/null 2> err_full
  echo "rc=$? left=$(ls -A small | tr '\n' ' ')"
}
mkdir -p small
if [ "$(id -u)" -eq 0 ]; then ns=(unshare -m); else ns=(unshare -rm); fi
for cmd in simulate estimate; do
  if [ $cmd = simulate ]; then args=(simulate --cycles 1 --quiet --out small/run); file=run/truth.csv
  else args=(estimate --data sig_sim/truth.csv --quiet --out small/run); file=run/estimates.csv; fi
  res=$("${ns[@]}" bash -c "$(declare -f disk_full); disk_full \"\$@\"" _ "$BMSSIM" "${args[@]}" 2>/dev/null)
  if [ $? -eq 77 ] || [ -z "$res" ]; then echo "ok - disk_full_$cmd # SKIP cannot mount a tmpfs here (not root, no user namespaces)"; continue; fi
  if [ "$res" = "rc=1 left=" ] && [ "$(wc -l < err_full)" -eq 1 ] &&
     grep -q "^bmssim: failure: no space left on device writing small/$file: free space or choose --out on another disk$" err_full; then
    pass "disk_full_$cmd ($res)"
  else fail "disk_full_$cmd" "$res: $(cat err_full)"; fi
done

echo "$PASSED passed, $FAILED failed"
[ "$FAILED" -eq 0 ]
