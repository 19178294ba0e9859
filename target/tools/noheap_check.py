#!/usr/bin/python3
"""Proof that the firmware uses no heap, no exceptions and no RTTI; run by ctest.

  noheap_check.py --nm NM --readelf READELF --objects FILE... [--strict-image ELF]
                  [--image ELF --map MAP] [--json OUT]

--objects      the project's own objects or archives in the image (the firmware tick, board
               support, the application). None may reference an allocator, operator new or
               delete, the exception runtime, unwinding or thread-safe-static guards, define
               typeinfo, or carry unwinding tables (.ARM.exidx/.ARM.extab/.eh_frame/
               .gcc_except_table sections).
--strict-image a linked image without libc stdio (bms_fw_image.elf): none of those symbols
               may exist in it at all, referenced or defined; its unwinding table (libgcc's
               helpers may bring a [cantunwind] entry) may cover no function of the objects.
--image/--map  a linked image with libc stdio (bms_replay.elf) and its linker map with --cref:
               heap symbols may be present (newlib's printf allocates) but referenced only from
               the toolchain's libraries, never from a project object; exception and RTTI
               symbols may not be present at all.
Exit status: 0 pass, 1 a forbidden reference, 2 bad usage.
"""
import argparse
import json
import re
import subprocess
import sys

HEAP = {"malloc", "free", "calloc", "realloc", "memalign", "aligned_alloc", "posix_memalign", "valloc",
        "pvalloc", "reallocf", "_malloc_r", "_free_r", "_calloc_r", "_realloc_r", "_memalign_r",
        "_sbrk", "_sbrk_r", "sbrk", "brk", "__malloc_lock", "__malloc_unlock"}
HEAP_RE = re.compile(r"^_Z(nw|na|dl|da)")  # operator new, new[], delete, delete[] (all overloads)
EXCEPTIONS = {"__cxa_allocate_exception", "__cxa_free_exception", "__cxa_throw", "__cxa_rethrow",
              "__cxa_begin_catch", "__cxa_end_catch", "__cxa_call_unexpected", "__cxa_end_cleanup",
              "__gxx_personality_v0", "__aeabi_unwind_cpp_pr0", "__aeabi_unwind_cpp_pr1",
              "__aeabi_unwind_cpp_pr2", "__cxa_guard_acquire", "__cxa_guard_release", "__cxa_guard_abort",
              "__dynamic_cast", "__cxa_bad_cast", "__cxa_bad_typeid"}
EXC_RE = re.compile(r"^(_Unwind_|__gnu_unwind_|_ZTI|_ZTS)")  # unwinder, typeinfo objects and names
UNWIND_SECTIONS = (".ARM.exidx", ".ARM.extab", ".eh_frame", ".gcc_except_table")
TOOLCHAIN_DIRS = ("/usr/lib/gcc/arm-none-eabi/", "/usr/lib/arm-none-eabi/")


def forbidden(name):
    if name in HEAP or HEAP_RE.match(name):
        return "heap"
    if name in EXCEPTIONS or EXC_RE.match(name):
        return "exceptions/rtti"
    return None


def run(cmd):
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)}: {p.stderr.strip()}")
    return p.stdout


def nm_symbols(nm, path):
    """(undefined, defined) symbol names of an object, archive or image."""
    und, dfn = set(), set()
    for line in run([nm, "-A", path]).splitlines():
        parts = line.rsplit(None, 2)
        if len(parts) < 2:
            continue
        if len(parts) == 2 or parts[-2] in ("U", "w", "v"):
            und.add(parts[-1])
        else:
            dfn.add(parts[-1])
    return und, dfn


def check_objects(a, report):
    problems = []
    own_defined = set()
    for path in a.objects:
        und, dfn = nm_symbols(a.nm, path)
        own_defined |= dfn
        for s in sorted(und):
            kind = forbidden(s)
            if kind:
                problems.append(f"{path}: references {s} ({kind})")
        for s in sorted(dfn):
            if forbidden(s) == "exceptions/rtti":
                problems.append(f"{path}: defines {s} (typeinfo)")
        sections = run([a.readelf, "-S", "-W", path])
        for sec in UNWIND_SECTIONS:
            if sec in sections:
                problems.append(f"{path}: has {sec} sections (unwinding tables)")
    report["objects"] = {"files": a.objects, "problems": list(problems)}
    print(f"noheap_check: {len(a.objects)} project objects/archives: "
          f"{'no heap, exception, unwinding or RTTI reference' if not problems else str(len(problems)) + ' problems'}")
    return problems, own_defined


def exidx_functions(readelf, image):
    out = run([readelf, "-u", image])
    return re.findall(r"^0x[0-9a-f]+ <([^>]+)>:\s*(.*)$", out, re.M)


def check_strict(a, own_defined, report):
    problems = []
    und, dfn = nm_symbols(a.nm, a.strict_image)
    present = sorted(s for s in und | dfn if forbidden(s))
    for s in present:
        problems.append(f"{a.strict_image}: contains {s} ({forbidden(s)})")
    entries = exidx_functions(a.readelf, a.strict_image)
    for fn, what in entries:
        if fn in own_defined:
            problems.append(f"{a.strict_image}: unwinding entry for the project's function {fn} ({what})")
    report["strict_image"] = {"image": a.strict_image, "forbidden_symbols": present,
                              "exidx_entries": [f"{f}: {w}" for f, w in entries], "problems": list(problems)}
    print(f"noheap_check: {a.strict_image}: {len(present)} heap/exception/RTTI symbols; unwinding table entries: "
          + (", ".join(f"{f} [{w.strip()}]" for f, w in entries) or "none"))
    return problems


def parse_cref(map_path):
    """Cross-reference table of a GNU ld map: symbol -> (defining file, [referencing files])."""
    table, sym = {}, None
    with open(map_path) as f:
        in_table = False
        for line in f:
            if line.startswith("Cross Reference Table"):
                in_table = True
                continue
            if not in_table or not line.strip() or line.startswith("Symbol "):
                continue
            if not line[0].isspace():
                parts = line.split(None, 1)
                sym = parts[0]
                table[sym] = [parts[1].strip() if len(parts) > 1 else "", []]
            elif sym:
                table[sym][1].append(line.strip())
    return table


def is_toolchain(path):
    return path.startswith(TOOLCHAIN_DIRS)


def check_image(a, report):
    problems = []
    und, dfn = nm_symbols(a.nm, a.image)
    for s in sorted(und | dfn):
        if forbidden(s) == "exceptions/rtti":
            problems.append(f"{a.image}: contains {s}")
    table = parse_cref(a.map)
    if not table:
        problems.append(f"{a.map}: no cross-reference table (link with -Wl,--cref)")
    heap_refs = {}
    for s, (definer, refs) in sorted(table.items()):
        if forbidden(s) != "heap":
            continue
        heap_refs[s] = {"defined_in": definer, "referenced_by": refs}
        for r in refs:
            if not is_toolchain(r):
                problems.append(f"{a.image}: {s} referenced by the project's {r}")
    report["image"] = {"image": a.image, "heap_symbols": heap_refs, "problems": list(problems)}
    libs = sorted({re.sub(r"^.*/", "", r) for v in heap_refs.values() for r in v["referenced_by"]})
    print(f"noheap_check: {a.image}: heap symbols {sorted(heap_refs) or 'none'}; referenced only by the "
          f"toolchain's libraries: {', '.join(libs) or '-'}")
    return problems


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--nm", required=True)
    ap.add_argument("--readelf", required=True)
    ap.add_argument("--objects", nargs="+", required=True)
    ap.add_argument("--strict-image")
    ap.add_argument("--image")
    ap.add_argument("--map")
    ap.add_argument("--json")
    a = ap.parse_args()
    if bool(a.image) != bool(a.map):
        print("noheap_check: --image and --map go together", file=sys.stderr)
        return 2
    report = {}
    try:
        problems, own_defined = check_objects(a, report)
        if a.strict_image:
            problems += check_strict(a, own_defined, report)
        if a.image:
            problems += check_image(a, report)
    except (OSError, RuntimeError) as e:
        print(f"noheap_check: {e}", file=sys.stderr)
        return 2
    report["problems"] = problems
    if a.json:
        with open(a.json, "w") as f:
            json.dump(report, f, indent=1)
    for p in problems:
        print(f"noheap_check: FAIL: {p}")
    if not problems:
        print("noheap_check: pass")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
