#!/usr/bin/env bash
# docs/architecture.md's one-tick list names files and functions that exist (issue 18), and the
# check fails when a step names a function that does not.
#   architecture_check_test.sh SOURCE_DIR
set -u
src="$1"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
fail=0
if python3 "$src/scripts/check-architecture.py" --root "$src"; then
  echo "PASS the one-tick list matches the code"
else
  echo "FAIL the one-tick list does not match the code (above)"; fail=1
fi
# A renamed function: the first step's function name gets a suffix the code does not have.
awk 'BEGIN{done=0} /^## One 0.2 s tick/{inside=1} inside && !done && /^1\. `/{sub(/`$/, "", $0); sub(/` /, "_renamed` ", $0); done=1} {print}' \
  "$src/docs/architecture.md" >"$tmp/renamed.md"
python3 "$src/scripts/check-architecture.py" --root "$src" --doc "$tmp/renamed.md" >"$tmp/out.txt" 2>&1
rc=$?
if [ $rc = 1 ] && grep -q "_renamed" "$tmp/out.txt"; then
  echo "PASS a step naming a missing function fails the check (exit $rc)"
else
  echo "FAIL a step naming a missing function: exit $rc"; cat "$tmp/out.txt"; fail=1
fi
# Numbering: steps must run 1, 2, 3.
sed '0,/^2\. `/s//4. `/' "$src/docs/architecture.md" >"$tmp/numbering.md"
python3 "$src/scripts/check-architecture.py" --root "$src" --doc "$tmp/numbering.md" >"$tmp/out2.txt" 2>&1
rc=$?
if [ $rc = 1 ] && grep -q "numbered 4, expected 2" "$tmp/out2.txt"; then
  echo "PASS a step out of order fails the check"
else
  echo "FAIL a step out of order: exit $rc"; cat "$tmp/out2.txt"; fail=1
fi
# One numbering: a tick step the code does not name so (or numbers otherwise) fails.
sed 's/tick step 7, \*\*resync\*\*/tick step 7, **re-synchronise**/' "$src/docs/architecture.md" >"$tmp/tick.md"
python3 "$src/scripts/check-architecture.py" --root "$src" --doc "$tmp/tick.md" >"$tmp/out3.txt" 2>&1
rc=$?
if [ $rc = 1 ] && grep -q "tick step 7 is 're-synchronise'" "$tmp/out3.txt"; then
  echo "PASS a tick step named otherwise than in BmsCore::tick fails the check"
else
  echo "FAIL a tick step named otherwise: exit $rc"; cat "$tmp/out3.txt"; fail=1
fi
exit $fail
