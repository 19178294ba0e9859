#!/usr/bin/env bash
# Records the estimator's golden per-tick traces (tests/golden/*.trace) anew, on purpose: after a
# change that is meant to change the estimator's outputs. Review `git diff tests/golden` (the
# first block that changed, and by how much) before committing it.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cmake --build "$root/build/host" --target test_golden
GLIBC_TUNABLES=glibc.cpu.hwcaps=-AVX2,-FMA BMS_GOLDEN_REGENERATE=1 "$root/build/host/tests/test_golden" --gtest_filter='GoldenTrace.*Profile*'
git -C "$root" diff --stat -- tests/golden
