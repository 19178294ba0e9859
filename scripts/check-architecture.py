#!/usr/bin/env python3
"""Checks that docs/architecture.md's one-tick list matches the code.

    scripts/check-architecture.py [--root DIR] [--doc FILE]

The section whose heading starts with "## One 0.2 s tick" holds a numbered list; every item
starts with `N. \`path:Name\`` (Name is `function`, `Class::function` or `ns::Class::function`).
For each item: the numbers run 1, 2, 3, ...; the file exists; every part of Name occurs in the
file as a word, and the last part as a function (`name(` or `name<...>(`) and only once
defined or declared there when the item says `Class::function`. A tick renamed, moved or
removed in the code makes this fail until the list is updated.

Exit 0 when every step matches, 1 naming each step that does not, 2 when the section or the
file is missing.
"""
import argparse
import os
import re
import sys

ITEM = re.compile(r"^(\d+)\.\s+`([^`:]+):([^`]+)`")


def tick_items(doc_path):
    try:
        with open(doc_path, encoding="utf-8") as f:
            lines = f.read().split("\n")
    except OSError as e:
        print(f"check-architecture: cannot read {doc_path}: {e.strerror}", file=sys.stderr)
        sys.exit(2)
    items, inside = [], False
    for number, line in enumerate(lines, 1):
        if line.startswith("## "):
            inside = line.startswith("## One 0.2 s tick")
            continue
        m = ITEM.match(line) if inside else None
        if m:
            items.append((number, int(m.group(1)), m.group(2), m.group(3)))
    return items


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
    items = tick_items(doc)
    if not items:
        print(f"check-architecture: {doc}: no numbered `path:function` list under '## One 0.2 s tick'",
              file=sys.stderr)
        return 2
    failures = []
    for expected, (doc_line, number, path, name) in enumerate(items, 1):
        if number != expected:
            failures.append(f"line {doc_line}: step numbered {number}, expected {expected}")
        problem = check_item(a.root, doc_line, path, name)
        if problem:
            failures.append(problem)
    for f in failures:
        print(f"check-architecture: {doc} {f}")
    print(f"check-architecture: {len(items)} steps, {len(failures)} mismatch(es)")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
