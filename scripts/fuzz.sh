#!/usr/bin/env bash
# Builds the libFuzzer targets of tests/fuzz with clang (ASan + UBSan) and runs each for a
# bounded time from its seed corpus in tests/fuzz/corpus/<target>/. Prints, per target,
# the executions and libFuzzer's coverage figures (cov: covered code edges, ft: features)
# and fails if any target finds a crash, a leak, UB or a timeout.
#
#   scripts/fuzz.sh [TARGET...]          default: every target
# Environment:
#   BMS_FUZZ_SECONDS   run time per target (default 30)
#   BMS_FUZZ_SEED      libFuzzer -seed (default 1: a repeatable run; 0 = random)
#   BMS_FUZZ_KEEP=1    keep build/fuzz/corpus/<target> from earlier runs (default: start
#                      from the seeds, so the figures are comparable between runs)
#   BMS_JOBS           build parallelism (default: nproc)
# Results: build/fuzz/summary.tsv and build/fuzz/logs/<target>.log; a crashing input is
# saved as build/fuzz/artifacts/<target>/crash-* (rerun: build/fuzz/fuzz_<target> FILE).
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
seconds="${BMS_FUZZ_SECONDS:-30}"
seed="${BMS_FUZZ_SEED:-1}"
jobs="${BMS_JOBS:-$(nproc 2>/dev/null || echo 2)}"
build="$root/build/fuzz"

all_targets=(can_receiver nvm_record lockstep_app nvm_payload expression bpx csv candump)
targets=("$@")
[ ${#targets[@]} -eq 0 ] && targets=("${all_targets[@]}")

# Largest input tried per target: a CAN record stream, one or two NVM slots, one
# expression, a BPX file, a short CSV/candump file.
max_len() {
  case "$1" in
    can_receiver) echo 1200 ;;
    nvm_record) echo 1100 ;;
    lockstep_app) echo 2200 ;;
    nvm_payload) echo 405 ;;
    expression) echo 1024 ;;
    bpx) echo 8192 ;;
    *) echo 4096 ;;
  esac
}

cmake -S tests/fuzz -B "$build" -G Ninja -DCMAKE_CXX_COMPILER=clang++ -DCMAKE_BUILD_TYPE=RelWithDebInfo >/dev/null
cmake --build "$build" -j "$jobs"

mkdir -p "$build/logs"
summary="$build/summary.tsv"
printf 'target\tseconds\texecutions\texec_per_s\tcov\tedges\tft\tcorpus\tresult\n' >"$summary"
failed=0
for t in "${targets[@]}"; do
  bin="$build/fuzz_$t"
  [ -x "$bin" ] || { echo "fuzz: no target '$t' (have: ${all_targets[*]})" >&2; exit 2; }
  work="$build/corpus/$t"
  art="$build/artifacts/$t"
  [ "${BMS_FUZZ_KEEP:-0}" = 1 ] || rm -rf "$work"
  mkdir -p "$work" "$art"
  dict=()
  [ -f "tests/fuzz/dict/$t.dict" ] && dict=("-dict=tests/fuzz/dict/$t.dict")
  log="$build/logs/$t.log"
  echo "== fuzz $t: ${seconds} s"
  rc=0
  # detect_leaks: the parsers must not leak on the error paths either.
  ASAN_OPTIONS="detect_leaks=1:abort_on_error=1" UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1" \
    "$bin" -max_total_time="$seconds" -seed="$seed" -max_len="$(max_len "$t")" -timeout=10 \
      -rss_limit_mb=2048 -print_final_stats=1 -artifact_prefix="$art/" "${dict[@]}" \
      "$work" "tests/fuzz/corpus/$t" >"$log" 2>&1 || rc=$?
  execs=$(sed -n 's/^stat::number_of_executed_units: *//p' "$log" | tail -1)
  # The last status line ("#N DONE cov: C ft: F corp: K/..." or "#N NEW/pulse ...").
  status=$(grep -E '^#[0-9]+' "$log" | tail -1 || true)
  cov=$(sed -n 's/.* cov: \([0-9]*\).*/\1/p' <<<"$status")
  ft=$(sed -n 's/.* ft: \([0-9]*\).*/\1/p' <<<"$status")
  corp=$(sed -n 's/.* corp: \([0-9]*\).*/\1/p' <<<"$status")
  rate=$(sed -n 's/^stat::average_exec_per_sec: *//p' "$log" | tail -1)
  # Instrumented edges in the whole binary (parser, harness, inlined library code): the
  # denominator of cov.
  edges=$(sed -n 's/^INFO: Loaded 1 modules *(\([0-9]*\) inline 8-bit counters).*/\1/p' "$log" | head -1)
  result=ok
  if [ "$rc" -ne 0 ]; then
    result="FAILED (exit $rc)"
    failed=1
  fi
  printf '%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\t%s\n' "$t" "$seconds" "${execs:-?}" "${rate:-?}" "${cov:-?}" \
    "${edges:-?}" "${ft:-?}" "${corp:-?}" "$result" >>"$summary"
  echo "   executions ${execs:-?} (${rate:-?}/s), cov ${cov:-?} of ${edges:-?} edges, ft ${ft:-?}, corpus ${corp:-?}: $result"
  if [ "$rc" -ne 0 ]; then
    grep -E 'ERROR: |SUMMARY: |runtime error|Test unit written to|deadly signal' "$log" | head -20 >&2 || true
    echo "   full log: $log" >&2
  fi
done
echo "== fuzz summary ($summary)"
column -t -s $'\t' "$summary" 2>/dev/null || cat "$summary"
exit "$failed"
