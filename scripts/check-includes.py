#!/usr/bin/env python3
"""Include direction: every #include in firmware/, hal/, apps/, target/ and host_sim/ points down the
layers (docs/architecture.md), never up. Exit 0 when every include is allowed, 1 (listing each
file:line, the include and the rule it breaks) otherwise, 2 for bad arguments.

    scripts/check-includes.py [--root DIR]

The layers, lowest first (a file's rule is the first whose folder holds it):
  firmware/include      the portable core: the C++ standard library, Eigen, bms/fw only; inside
                        it model/ includes only model/, estimation/ only model/ and itself,
                        cells/ only model/ and itself (can/, nvm/, config/ any of the core)
  hal/include/bms/hal   HAL interfaces: the standard library, bms/hal (no firmware, no backend);
                        hal/include/bms/hal/linux and the Linux, Cortex-M and fake backends also
                        their system's headers
  firmware/app          the application: bms/fw, bms/app and the HAL interfaces (no backend)
  apps/, target/        the programs: everything below them
  host_sim/src/cell/cell_parameters.hpp, scalar_function.hpp
                        the cell's parameter types: the standard library only
  host_sim/src/io       the host's parsers: the standard library, fmt, nlohmann, io/ and the
                        cell's parameter types they fill
  host_sim/src, app     the host tool: anything but its command layer (app/) from src/
"""
import argparse
import os
import re
import sys

INCLUDE = re.compile(r'^\s*#\s*include\s*([<"])([^>"]+)[>"]')
STD = r"[a-z_0-9]+"            # <cmath>, <vector>: the C++ standard library
SYSTEM = r"[A-Za-z_0-9/]+\.h"  # <unistd.h>, <sys/socket.h>, <linux/can.h>: the system's C headers
LOCAL = "LOCAL"  # "errno_text.hpp": a header in the same folder (checked on disk)
HAL_IF = r"bms/hal/[a-z_0-9]+\.hpp"  # the HAL interfaces (not a backend's folder)
HOST_SRC = r"(io|cell|dfn|sim|studies|estimation|diagnosis|baselines|hil)/.+"
PARAM_TYPES = r"cell/(cell_parameters|scalar_function)\.hpp"  # header-only types the parsers fill
THIRD_PARTY = r"(Eigen|fmt|nlohmann|CLI|sundials|sunmatrix|sunlinsol|nvector|gtest|benchmark)/.+|klu\.h"

# (folder prefix, what its files may include, the layer's name). First match wins.
RULES = [
    # The core's folders by job, lowest first: model < estimation < can, nvm, config, cells.
    ("firmware/include/bms/fw/model/", [STD, r"Eigen/.+", r"bms/fw/model/.+"], "the core's model (std, Eigen, model/)"),
    ("firmware/include/bms/fw/estimation/", [STD, r"Eigen/.+", r"bms/fw/(model|estimation)/.+"],
     "the core's estimation (model/, estimation/)"),
    ("firmware/include/bms/fw/cells/", [STD, r"Eigen/.+", r"bms/fw/(model|cells)/.+"], "a cell's traits (model/)"),
    ("firmware/include/bms/fw/", [STD, r"Eigen/.+", r"bms/fw/.+"], "the firmware core (std, Eigen, bms/fw)"),
    ("firmware/app/", [STD, r"bms/fw/.+", r"bms/app/.+", HAL_IF], "the application (bms/fw, bms/app, HAL interfaces)"),
    ("hal/include/bms/hal/linux/", [STD, SYSTEM, r"bms/hal/.+", LOCAL], "the Linux backend"),
    ("hal/include/bms/hal/fake/", [STD, r"bms/hal/.+", LOCAL], "the fakes"),
    ("hal/include/bms/hal/cortex_m/", [STD, SYSTEM, r"bms/hal/.+", LOCAL], "the Cortex-M backend"),
    ("hal/include/", [STD, r"bms/hal/[a-z_0-9/]+\.hpp", LOCAL], "the HAL interfaces (std, bms/hal)"),
    ("apps/", [STD, SYSTEM, r"bms/.+", LOCAL], "the Linux program"),
    ("hal/", [STD, SYSTEM, r"bms/hal/.+", LOCAL], "a HAL backend (std, system, bms/hal)"),
    ("target/", [STD, SYSTEM, r"bms/.+", LOCAL, r"replay_data\.hpp|fw_source_hash\.hpp"], "the board applications"),
    # The cell's parameter types: the vocabulary the parsers fill, below them (std only).
    ("host_sim/src/cell/scalar_function.hpp", [STD], "the cell's parameter types (std)"),
    ("host_sim/src/cell/cell_parameters.hpp", [STD, r"cell/scalar_function\.hpp"], "the cell's parameter types (std)"),
    ("host_sim/src/io/", [STD, SYSTEM, r"fmt/.+", r"nlohmann/.+", r"io/.+", PARAM_TYPES, LOCAL],
     "the host's parsers (io/ and the cell's parameter types)"),
    ("host_sim/src/", [STD, SYSTEM, THIRD_PARTY, r"bms/(fw|hal)/.+", HOST_SRC, LOCAL], "the host's libraries (src/)"),
    ("host_sim/app/", [STD, SYSTEM, THIRD_PARTY, r"bms/(fw|hal)/.+", HOST_SRC, LOCAL], "the host tool (app/)"),
]
# Upward includes allowed by name (none today; a new one must be named here to pass).
KNOWN_UP = set()
ROOTS = ["firmware", "hal", "apps", "target", "host_sim"]
SUFFIXES = (".hpp", ".cpp", ".h", ".c")


def rule_for(rel):
    for prefix, allowed, name in RULES:
        if rel.startswith(prefix):
            return allowed, name
    return None, None


def check_file(root, rel):
    allowed, name = rule_for(rel)
    if allowed is None:
        return []
    problems = []
    with open(os.path.join(root, rel), encoding="utf-8", errors="replace") as f:
        for number, line in enumerate(f, 1):
            m = INCLUDE.match(line)
            if not m:
                continue
            target = m.group(2)
            if (rel, target) in KNOWN_UP:
                continue
            local = m.group(1) == '"' and os.path.isfile(os.path.join(root, os.path.dirname(rel), target))
            if not (local and LOCAL in allowed) and not any(p != LOCAL and re.fullmatch(p, target) for p in allowed):
                close = ">" if m.group(1) == "<" else '"'
                problems.append(f"{rel}:{number}: includes {m.group(1)}{target}{close}: not allowed in {name}")
    return problems


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--root", default=os.path.join(os.path.dirname(os.path.abspath(__file__)), ".."))
    a = ap.parse_args()
    if not os.path.isdir(os.path.join(a.root, "firmware")):
        print(f"check-includes: {a.root}: no firmware/ folder (give the source tree with --root)", file=sys.stderr)
        return 2
    problems, files = [], 0
    for top in ROOTS:
        for dirpath, dirnames, filenames in os.walk(os.path.join(a.root, top)):
            dirnames[:] = sorted(d for d in dirnames if d != "build" and not d.startswith("."))
            for fn in sorted(filenames):
                if fn.endswith(SUFFIXES):
                    files += 1
                    problems += check_file(a.root, os.path.relpath(os.path.join(dirpath, fn), a.root))
    for p in problems:
        print(p)
    print(f"check-includes: {files} files, {len(problems)} upward includes, {len(KNOWN_UP)} known ones allowed")
    return 1 if problems else 0


if __name__ == "__main__":
    sys.exit(main())
