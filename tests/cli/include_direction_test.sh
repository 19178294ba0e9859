#!/usr/bin/env bash
# Include direction (scripts/check-includes.py): the tree passes, and a planted upward include
# (a canary) in each of four layers fails it with exit 1 naming the file and the include.
#   include_direction_test.sh SOURCE_DIR
set -u
src="$1"
check="$src/scripts/check-includes.py"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
fail=0
if out="$(python3 "$check" --root "$src" 2>&1)"; then
  echo "PASS the tree: $(tail -1 <<<"$out")"
else
  echo "FAIL the tree has upward includes:"; echo "$out"; fail=1
fi
# canary NAME FILE INCLUDE: a copy of the tree with INCLUDE appended to FILE fails the check.
canary() {
  local name=$1 file=$2 inc=$3 out rc
  rm -rf "$tmp/tree"; mkdir -p "$tmp/tree"
  (cd "$src" && tar cf - --exclude=build --exclude=.git firmware hal apps target host_sim) | (cd "$tmp/tree" && tar xf -)
  printf '#include %s\n' "$inc" >> "$tmp/tree/$file"
  out="$(python3 "$check" --root "$tmp/tree" 2>&1)"; rc=$?
  if [ $rc = 1 ] && grep -qF -- "$file" <<<"$out" && grep -qF -- "${inc:1:${#inc}-2}" <<<"$out"; then
    echo "PASS canary $name: $(grep -F -- "$file" <<<"$out" | head -1)"
  else
    echo "FAIL canary $name: exit $rc, expected 1 naming $file and $inc"; echo "$out"; fail=1
  fi
}
canary core-includes-hal firmware/include/bms/fw/model/dual.hpp '"bms/hal/can_bus.hpp"'
canary model-includes-estimation firmware/include/bms/fw/model/reduced_cell.hpp '"bms/fw/estimation/rls.hpp"'
canary estimation-includes-can firmware/include/bms/fw/estimation/bms_core.hpp '"bms/fw/can/can_messages.hpp"'
canary linux-program-includes-host apps/linux/bms_firmware.cpp '"sim/cycler.hpp"'
canary hal-includes-firmware hal/include/bms/hal/can_bus.hpp '"bms/fw/estimation/bms_core.hpp"'
canary app-includes-backend firmware/app/include/bms/app/tick_supervisor.hpp '"bms/hal/linux/socketcan.hpp"'
canary io-includes-sim host_sim/src/io/csv_table.hpp '"sim/cycler.hpp"'
canary src-includes-app host_sim/src/estimation/estimate_run.hpp '"commands.hpp"'
exit $fail
