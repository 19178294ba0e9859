#!/usr/bin/env bash
# docs/architecture.md's one-tick list names files and functions that exist, and the
# check fails when a step names a function that does not, is out of order, or names a tick step
# otherwise than BmsCore::tick's own list.
#   architecture_check_test.sh SOURCE_DIR
set -u
src="$1"
tmp="$(mktemp -d)"
trap 'rm -rf "$tmp"' EXIT
fail=0
check="$src/scripts/check-architecture.py"
if python3 "$check" --root "$src"; then
  echo "PASS the one-tick list matches the code"
else
  echo "FAIL the one-tick list does not match the code (above)"; fail=1
fi
# expect_failure NAME EXPECTED-TEXT: the check on $tmp/NAME.md exits 1 and says EXPECTED-TEXT.
expect_failure() {
  local out rc
  out="$(python3 "$check" --root "$src" --doc "$tmp/$1.md" 2>&1)"
  rc=$?
  if [ $rc = 1 ] && grep -qF -- "$2" <<<"$out"; then
    echo "PASS $1: the check fails (exit 1) saying \"$2\""
  else
    echo "FAIL $1: exit $rc, expected 1 and \"$2\""; echo "$out"; fail=1
  fi
}
doc="$src/docs/architecture.md"
# A renamed function: the first step's first name gets a suffix the code does not have.
awk '/^## One 0.2 s tick/{inside=1} inside && !done && /^1\. `/{sub(/` /, "_renamed` "); done=1} {print}' "$doc" >"$tmp/renamed.md"
expect_failure renamed "_renamed"
sed '0,/^2\. `/s//4. `/' "$doc" >"$tmp/numbering.md"
expect_failure numbering "numbered 4, expected 2"
sed 's/tick step 7, \*\*resync\*\*/tick step 7, **re-synchronise**/' "$doc" >"$tmp/tick.md"
expect_failure tick "tick step 7 is 're-synchronise'"
exit $fail
