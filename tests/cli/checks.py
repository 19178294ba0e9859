"""The CLI tests' check for their Python blocks: each check prints its line, and a block ends with
`sys.exit(0 if passed() else 1)` so that one failed check fails the block after all are printed.
Import it with PYTHONPATH set to tests/cli (the shell tests export it)."""

_ok = True


def check(cond, what):
    global _ok
    print(("  ok: " if cond else "  FAILED: ") + what)
    _ok = _ok and bool(cond)


def passed():
    return _ok
