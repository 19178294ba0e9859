#!/usr/bin/env python3
"""Lists C++ functions longer than a limit (default 80 lines) under the given folders.

    scripts/function-length.py [--max-lines N] [--check] DIR...

A function is a brace block whose head ends in a parameter list (plus qualifiers, a
trailing return type or a constructor's initialiser list) and whose enclosing scopes are
only namespaces, classes, structs or `extern "C"`: a lambda counts as part of the function
around it. A function may stay longer when the comment just above its head says why and
contains the words "long on purpose". Lines counted: head's opening brace to closing brace.

With --check the exit status is 1 when a function is over the limit (the ctest), else 0.
Exit 2 on a folder that does not exist.
"""
import argparse
import os
import re
import sys

EXTS = (".cpp", ".hpp", ".h", ".cc", ".c")
CONTROL = re.compile(r"\b(if|for|while|switch|catch|do|else|try)\s*(\(|$)")
SCOPE = re.compile(r"\b(namespace|class|struct|union|enum)\b[^()]*$|extern\s+\"C\"\s*$")
FUNC_HEAD = re.compile(
    r"\)\s*(const|noexcept(\([^)]*\))?|override|final|mutable|constexpr|&|&&|\s)*"
    r"(->\s*[\w:<>,\s*&]+)?\s*$")
REASON = "long on purpose"  # compared case-insensitively


def strip_code(text):
    """Comments and string/char literals blanked out, newlines kept (line numbers hold)."""
    out = []
    i, n = 0, len(text)
    while i < n:
        c = text[i]
        if text.startswith("//", i):
            j = text.find("\n", i)
            j = n if j < 0 else j
            out.append(" " * (j - i))
            i = j
        elif text.startswith("/*", i):
            j = text.find("*/", i + 2)
            j = n if j < 0 else j + 2
            out.append("".join(ch if ch == "\n" else " " for ch in text[i:j]))
            i = j
        elif c == 'R' and text.startswith('R"', i):
            m = re.match(r'R"([^(\s]*)\(', text[i:])
            if not m:
                out.append(c)
                i += 1
                continue
            end = text.find(")" + m.group(1) + '"', i)
            j = n if end < 0 else end + len(m.group(1)) + 2
            out.append("".join(ch if ch == "\n" else " " for ch in text[i:j]))
            i = j
        elif c in "\"'":
            j = i + 1
            while j < n and text[j] != c:
                j += 2 if text[j] == "\\" else 1
            out.append(c + " " * (min(j, n) - i - 1) + (c if j < n else ""))
            i = j + 1
        else:
            out.append(c)
            i += 1
    return "".join(out)


def head_before(code, pos):
    """The text between the previous ; { } (or a preprocessor line) and position pos."""
    j = pos - 1
    depth = 0
    while j >= 0:
        ch = code[j]
        if ch in ")]":
            depth += 1
        elif ch in "([":
            depth -= 1
        elif depth == 0 and ch in ";{}":
            break
        j -= 1
    head = code[j + 1:pos]
    lines = [ln for ln in head.split("\n") if not ln.lstrip().startswith("#")]
    return "\n".join(lines), j + 1


def is_function_head(head):
    flat = " ".join(head.split())
    if not flat or CONTROL.search(flat) or "=" in flat.split("(")[0]:
        return False
    if re.search(r"\]\s*(\([^)]*\))?\s*(mutable\s*)?(->.*)?$", flat):
        return False  # a lambda
    # A constructor's initialiser list: `) : a_(x), b_(y)` before the body.
    m = re.search(r"\)\s*(noexcept\s*)?:\s*[\w:]+\s*[({]", flat)
    if m:
        return True
    return bool(FUNC_HEAD.search(flat)) and "(" in flat


def name_of(head):
    flat = " ".join(head.split())
    m = re.search(r"([\w:~]+(?:operator\s*[^\s(]+)?)\s*\(", flat)
    return m.group(1) if m else flat[:40]


def long_functions(path, max_lines):
    with open(path, encoding="utf-8", errors="replace") as f:
        text = f.read()
    code = strip_code(text)
    raw_lines = text.split("\n")
    found = []
    stack = []  # (kind, start_offset, head)
    for pos, ch in enumerate(code):
        if ch == "{":
            enclosing_ok = all(k == "scope" for k, _, _ in stack)
            head, head_start = head_before(code, pos)
            if enclosing_ok and SCOPE.search(" ".join(head.split())):
                stack.append(("scope", pos, head))
            elif enclosing_ok and is_function_head(head):
                stack.append(("function", pos, (head, head_start)))
            else:
                stack.append(("block", pos, head))
        elif ch == "}" and stack:
            kind, start, info = stack.pop()
            if kind != "function":
                continue
            first = code.count("\n", 0, start) + 1
            last = code.count("\n", 0, pos) + 1
            lines = last - first + 1
            if lines <= max_lines:
                continue
            head, head_start = info
            head_line = code.count("\n", 0, head_start + len(head) - len(head.lstrip())) + 1
            above = "\n".join(raw_lines[max(0, head_line - 6):head_line + 1])
            if REASON in above.lower():
                continue
            found.append((path, head_line, name_of(head), lines))
    return found


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("dirs", nargs="+", help="folders to scan (recursively)")
    ap.add_argument("--max-lines", type=int, default=80, help="longest allowed function (default 80)")
    ap.add_argument("--check", action="store_true", help="exit 1 when a function is over the limit")
    a = ap.parse_args()
    results = []
    for d in a.dirs:
        if not os.path.isdir(d):
            print(f"function-length: no such folder: {d}", file=sys.stderr)
            return 2
        for root, _, files in os.walk(d):
            for fn in sorted(files):
                if fn.endswith(EXTS):
                    results += long_functions(os.path.join(root, fn), a.max_lines)
    results.sort(key=lambda r: -r[3])
    for path, line, name, lines in results:
        print(f"{path}:{line}: {name}: {lines} lines (limit {a.max_lines})")
    print(f"function-length: {len(results)} function(s) over {a.max_lines} lines in {' '.join(a.dirs)}")
    return 1 if (a.check and results) else 0


if __name__ == "__main__":
    sys.exit(main())
