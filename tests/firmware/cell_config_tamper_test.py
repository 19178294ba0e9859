#!/usr/bin/python3
"""A firmware build never holds a cell configuration whose CRC or schema does not match.

usage: cell_config_tamper_test.py CXX SOURCE_DIR WORK_DIR [EXTRA_INCLUDE_DIR...]

Compiles a translation unit that selects the LCO cell (BMS_CELL_ID=1, as -DBMS_CELL=lco does)
through bms/fw/config/cell_choice.hpp, first over the committed header (the control: it must
compile), then over copies of it placed first on the include path, each changed one way:
  - one number of the record changed in its last bits (kAreaM2) -> the CRC static_assert;
  - one value of the OCP table changed, last bits                      -> the CRC static_assert;
  - the design-time bias changed, last bits (kModelBiasOhm)          -> the CRC static_assert;
  - one knot of the bias table changed, last bits (kModelBiasTableOhm) -> the CRC static_assert;
  - one knot of the rich level changed (kModelBiasRichOhm)          -> the CRC static_assert;
  - the inventory levels' step changed (kModelBiasInventoryStep 0.01 -> 0.02) -> the CRC static_assert;
  - the trusted span's end changed (kModelBiasTableTrustedLast 0 -> 0.7) -> the CRC static_assert;
  - the schema the header states changed (2 -> 3)                   -> the schema static_assert;
  - a field removed (kSideAlpha)                                    -> an error naming kSideAlpha.
Each must fail to compile with its message. Exit 0 when all do, 1 otherwise.
"""
import os
import re
import shutil
import subprocess
import sys

UNIT = """#include "bms/fw/config/cell_choice.hpp"
#include "bms/fw/model/reduced_cell.hpp"
// What an image of the build's cell instantiates: the model and its nominal cell.
using Cell = bms::fw::SelectedCell;
double probe() { return bms::fw::nominal_cell_of<double, Cell>().inventory_mol; }
"""


def compile_unit(cxx, includes, work):
    unit = os.path.join(work, "unit.cpp")
    with open(unit, "w") as f:
        f.write(UNIT)
    cmd = [cxx, "-std=c++17", "-fsyntax-only", "-DBMS_CELL_ID=1"] + [f"-I{d}" for d in includes] + [unit]
    r = subprocess.run(cmd, capture_output=True, text=True)
    return r.returncode, r.stderr


def main():
    if len(sys.argv) < 4:
        print(__doc__, file=sys.stderr)
        return 2
    cxx, src, work = sys.argv[1:4]
    extra = sys.argv[4:]
    header = os.path.join(src, "firmware/include/bms/fw/cells/lco_cell.hpp")
    text = open(header).read()
    shutil.rmtree(work, ignore_errors=True)
    os.makedirs(work)
    base = [os.path.join(src, "firmware/include")] + extra
    ok = True
    rc, err = compile_unit(cxx, base, work)
    good = rc == 0
    ok &= good
    print(f"{'PASS' if good else 'FAIL'} control: the committed lco_cell.hpp compiles" + ("" if good else "\n" + err[-2000:]))

    def nudge(number):  # the next-but-one double up: a change in the last bits only
        v = float(number)
        w = v * (1.0 + 5e-16) if v != 0.0 else 5e-324
        assert w != v
        return repr(w)

    cases = [
        ("a record number changed (kAreaM2)",
         re.sub(r"(kAreaM2 = )([0-9.e+-]+)", lambda m: m.group(1) + nudge(m.group(2)), text, count=1), r"CRC-32 of the header's numbers"),
        ("an OCP table value changed",
         re.sub(r"(kOcpPos\{[^{]*\{)([0-9.e+-]+)", lambda m: m.group(1) + nudge(m.group(2)), text, count=1), r"CRC-32 of the header's numbers"),
        ("the model bias changed (kModelBiasOhm)",
         re.sub(r"(kModelBiasOhm = )([0-9.e+-]+)", lambda m: m.group(1) + nudge(m.group(2)), text, count=1), r"CRC-32 of the header's numbers"),
        ("a bias table knot changed (kModelBiasTableOhm)",
         re.sub(r"(kModelBiasTableOhm\[[0-9]+\] = \{\s*)([0-9.e+-]+)", lambda m: m.group(1) + nudge(m.group(2)), text, count=1),
         r"CRC-32 of the header's numbers"),
        ("a rich-level knot changed (kModelBiasRichOhm)",
         re.sub(r"(kModelBiasRichOhm\[[0-9]+\] = \{\s*)([0-9.e+-]+)", lambda m: m.group(1) + nudge(m.group(2)), text, count=1),
         r"CRC-32 of the header's numbers"),
        ("the inventory step changed (kModelBiasInventoryStep)",
         text.replace("kModelBiasInventoryStep = 0.01;", "kModelBiasInventoryStep = 0.02;"),
         r"CRC-32 of the header's numbers"),
        ("the trusted span's end changed (kModelBiasTableTrustedLast)",
         text.replace("kModelBiasTableTrustedLast = 0.0;", "kModelBiasTableTrustedLast = 0.7;"),
         r"CRC-32 of the header's numbers"),
        ("the calibration's coverage changed (kModelBiasConstantAloneCovered)",
         re.sub(r"kModelBiasConstantAloneCovered = ([0-9.]+);",
                lambda m: "kModelBiasConstantAloneCovered = %s;" % ("1.0" if float(m.group(1)) == 0.0 else "0.0"), text),
         r"CRC-32 of the header's numbers"),
        ("the schema changed",
         re.sub(r"static_assert\(kCellConfigSchema == (\d+)",
                lambda m: "static_assert(kCellConfigSchema == %d" % (int(m.group(1)) + 1), text),
         r"generated for cell configuration schema"),
        ("a field removed (kSideAlpha)",
         re.sub(r"\n  static constexpr double kSideAlpha = [^\n]*", "", text), r"kSideAlpha"),
    ]
    for name, tampered, expect in cases:
        if tampered == text:
            print(f"FAIL {name}: the test could not change the header")
            ok = False
            continue
        d = os.path.join(work, re.sub(r"[^a-z]+", "_", name.lower()))
        os.makedirs(os.path.join(d, "bms/fw/cells"))
        with open(os.path.join(d, "bms/fw/cells/lco_cell.hpp"), "w") as f:
            f.write(tampered)
        rc, err = compile_unit(cxx, [d] + base, work)
        good = rc != 0 and re.search(expect, err) is not None
        ok &= good
        first = next((line for line in err.splitlines() if "error" in line), "compiled")
        print(f"{'PASS' if good else 'FAIL'} {name}: refused at build: {first.strip()[:200]}")
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
