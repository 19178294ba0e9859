#!/usr/bin/env python3
"""Checks that docs/architecture.md's one-tick list matches the code.

    scripts/check-architecture.py [--root DIR] [--doc FILE]

The section whose heading starts with "## One 0.2 s tick" holds a numbered list (the path, 1, 2,
3, ...) whose items name code as `path:Name` (Name is `function`, `Class::function` or a
`kConstant`). Every such name in the section is checked: the file exists, every part of Name
occurs in it as a word, and a function's name as `name(` (or `name<...>(`). The section's
"tick step N, **name**" bullets must be the list written at the top of BmsCore::tick
(firmware/include/bms/fw/estimation/bms_core.hpp: `//   N name   ...`), same numbers, same names, all of
them: one numbering of the tick in the code and the document. A step renamed, moved or
removed in the code makes this fail until the list is updated.

Exit 0 when every step matches, 1 naming each step that does not, 2 when the section or the
file is missing.
"""
import argparse
import os
import re
import sys

ITEM = re.compile(r"^(\d+)\.\s")
REF = re.compile(r"`([\w./-]+\.(?:hpp|cpp|h|c|py|sh)):([\w:~]+)`")
TICK_DOC = re.compile(r"tick step (\d+), \*\*([^*]+)\*\*")
TICK_CODE = re.compile(r"^\s*//\s+(\d+) (\S+(?: \S+)*?)\s{2,}\S")
CORE = "firmware/include/bms/fw/estimation/bms_core.hpp"


def read_section(doc_path):
    """(numbered items, code references, tick steps) of the one-tick section."""
    try:
        with open(doc_path, encoding="utf-8") as f:
            lines = f.read().split("\n")
    except OSError as e:
        print(f"check-architecture: cannot read {doc_path}: {e.strerror}", file=sys.stderr)
        sys.exit(2)
    items, refs, steps, inside = [], [], [], False
    for number, line in enumerate(lines, 1):
        if line.startswith("## "):
            inside = line.startswith("## One 0.2 s tick")
            continue
        if not inside:
            continue
        m = ITEM.match(line)
        if m:
            items.append((number, int(m.group(1))))
        refs += [(number, r.group(1), r.group(2)) for r in REF.finditer(line)]
        steps += [(number, int(t.group(1)), t.group(2)) for t in TICK_DOC.finditer(line)]
    return items, refs, steps


def code_tick_steps(root):
    """The numbered list at the top of BmsCore::tick: {number: name}."""
    with open(os.path.join(root, CORE), encoding="utf-8") as f:
        text = f.read()
    body = text[text.index("Output tick("):]
    body = body[:body.index("StatusWord st")]
    return {int(m.group(1)): m.group(2) for m in map(TICK_CODE.match, body.split("\n")) if m}


def check_item(root, doc_line, path, name):
    full = os.path.join(root, path)
    if not os.path.isfile(full):
        return f"line {doc_line}: {path} does not exist"
    with open(full, encoding="utf-8", errors="replace") as f:
        text = f.read()
    parts = name.split("::")
    for part in parts:
        if not re.search(r"\b" + re.escape(part) + r"\b", text):
            return f"line {doc_line}: {path} has no '{part}' (step {name})"
    fn = parts[-1]
    if re.match(r"k[A-Z]", fn):
        return None  # a constant: present is enough
    if not re.search(r"\b" + re.escape(fn) + r"\s*(<[^;{}()]*>)?\s*\(", text):
        return f"line {doc_line}: {path} has no function '{fn}(' (step {name})"
    return None


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    here = os.path.dirname(os.path.abspath(__file__))
    ap.add_argument("--root", default=os.path.dirname(here), help="the project's root (default: this script's ..)")
    ap.add_argument("--doc", help="the document to check (default: ROOT/docs/architecture.md)")
    a = ap.parse_args()
    doc = a.doc or os.path.join(a.root, "docs", "architecture.md")
    items, refs, steps = read_section(doc)
    if not items or not refs:
        print(f"check-architecture: {doc}: no numbered list naming `path:function` under '## One 0.2 s tick'",
              file=sys.stderr)
        return 2
    failures = []
    for expected, (doc_line, number) in enumerate(items, 1):
        if number != expected:
            failures.append(f"line {doc_line}: step numbered {number}, expected {expected}")
    for doc_line, path, name in refs:
        problem = check_item(a.root, doc_line, path, name)
        if problem:
            failures.append(problem)
    code_steps = code_tick_steps(a.root)
    doc_steps = {n: name for _, n, name in steps}
    for doc_line, n, name in steps:
        if code_steps.get(n) != name:
            failures.append(f"line {doc_line}: tick step {n} is '{name}', {CORE} says '{code_steps.get(n)}'")
    for n in sorted(set(code_steps) - set(doc_steps)):
        failures.append(f"tick step {n} ('{code_steps[n]}') of {CORE} is not in the list")
    for f in failures:
        print(f"check-architecture: {doc} {f}")
    print(f"check-architecture: {len(items)} path steps, {len(steps)} tick steps, {len(refs)} names, "
          f"{len(failures)} mismatch(es)")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
