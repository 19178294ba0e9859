#!/usr/bin/env bash
# Reproduces the numbers of docs/results/target.md: builds the host reference and
# both board presets when missing, runs the board tests verbosely and prints their reports.
#   scripts/target-results.sh [cortex-m7|cortex-m4f]...   (default: both)
# The JSON behind each report: build/<preset>/target/results/*.json.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
presets=("$@")
[ ${#presets[@]} -eq 0 ] && presets=(cortex-m7 cortex-m4f)
# The host reference must be built from the same sources as the images (the comparison checks
# the firmware source hash): rebuild its two executables whenever the host build exists.
if [ -f build/host/build.ninja ]; then
  cmake --build build/host -j1 --target bms_replay_host bms_replay_host_float >/dev/null
else
  ./bms build host >/dev/null
fi
for p in "${presets[@]}"; do
  ./bms build "$p" >/dev/null
  echo "===================== preset $p"
  # -V prints each test's report; keep the reports, drop ctest's own bookkeeping lines.
  ctest --preset "$p" -V 2>&1 | sed -n 's/^[0-9]*: //p' |
    grep -v -E '^(Test command|Working Directory|Environment variables|Test timeout|Test time|info: pass)' |
    grep -v -E '^ {5,}' || true
  ctest --preset "$p" 2>&1 | grep -E 'tests passed|Failed' || true
done
