#!/usr/bin/python3
"""Footprint of a linked Cortex-M image: flash, static RAM, worst-case stack.

  footprint.py --image ELF --map MAP --build-dir DIR [--tools-prefix arm-none-eabi-]
               [--entry NAME=SYMBOL]... [--isr SYMBOL]... [--exception-frame BYTES]
               [--indirect SYMBOL=REGEX]... [--limit-flash B] [--limit-ram B] [--limit-stack B]
               [--stack-check NAME] [--json OUT]

Flash  = everything stored in flash: vector table, code, read-only data, unwinding tables,
         constructor tables and the initial values of .data. Reported with and without the
         replay data (the bms_replay_* arrays: test input, not firmware).
RAM    = .data + .bss + .noinit (static RAM). The linker script's heap (libc only) and stack
         reservations are reported apart; they are sizes chosen in mps2.ld, not measurements.
Origin = the map file's input sections grouped by where they come from (firmware tick, board
         support, application, replay data, newlib, libgcc).
Stack  = worst case along the call graph from each --entry: -fstack-usage frames and
         -fcallgraph-info=su edges (the .ci files next to the project's objects in
         --build-dir); functions without a .ci file (newlib, libgcc) are taken from the image's
         disassembly (every push/vpush/sub sp of the function, summed: an upper bound), their
         callees from its bl/b.w instructions. Indirect calls are resolved by --indirect
         CALLER=REGEX (candidates: functions whose symbol matches REGEX), __libc_init_array's from
         the image's .init_array. Recursion, dynamic frames and unresolved indirect calls are
         reported; then the entry's bound is marked incomplete. Interrupts: the deepest --isr
         plus the exception frame (104 bytes with the FPU's lazy-stacked context + 4 for
         alignment) come on top of --stack-check's entry.
Exit status: 0 within the limits, 1 over a limit or an incomplete stack bound, 2 bad usage.
"""
import argparse
import bisect
import glob
import json
import os
import re
import subprocess
import sys

FLASH_SECTIONS = (".isr_vector", ".text", ".rodata", ".ARM.extab", ".ARM.exidx", ".preinit_array",
                  ".init_array", ".fini_array", ".data")
RAM_SECTIONS = (".data", ".bss", ".noinit")
REPLAY_DATA_PREFIX = "bms_replay_"


def run(cmd):
    p = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    if p.returncode != 0:
        raise RuntimeError(f"{' '.join(cmd)}: {p.stderr.strip()}")
    return p.stdout


def sections(readelf, image):
    out = {}
    for m in re.finditer(r"^\s*\[\s*\d+\]\s+(\S+)\s+\S+\s+([0-9a-f]+)\s+[0-9a-f]+\s+([0-9a-f]+)", run([readelf, "-S", "-W", image]), re.M):
        out[m.group(1)] = {"address": int(m.group(2), 16), "size": int(m.group(3), 16)}
    return out


def symbol_addresses(nm, image):
    out = {}
    for line in run([nm, "--defined-only", image]).splitlines():
        p = line.split()
        if len(p) == 3 and p[1] in "tTwW":
            out[p[2]] = int(p[0], 16) & ~1
    return out


def symbol_sizes(nm, image):
    sizes = {}
    for line in run([nm, "-S", "--defined-only", image]).splitlines():
        parts = line.split()
        if len(parts) == 4:
            sizes[parts[3]] = int(parts[1], 16)
    return sizes


def origin(path):
    p = path.replace("\\", "/")
    if "bms_fw_tick" in p:
        return "firmware tick (bms_fw_tick: BmsCore, ReducedCell, RcsiEstimator)"
    if "bms_replay_data" in p or "replay_data.cpp" in p:
        return "replay data (test input)"
    if "cortex_m" in p or "bms_board" in p:
        return "board support (hal/cortex_m)"
    if "/target/CMakeFiles/" in p or p.startswith("target/CMakeFiles/"):
        return "application (target/*main.cpp, platform)"
    if "libgcc" in p:
        return "libgcc (compiler runtime)"
    if "libstdc++" in p or "libsupc++" in p:
        return "libstdc++"
    if "arm-none-eabi" in p:
        return "newlib (libc, libm, rdimon)"
    return "other (linker)"


def map_origins(map_path, wanted):
    """Bytes per origin and output section, from the input-section lines of a GNU ld map."""
    totals, objects = {}, set()
    out_sec, pending = None, None
    in_map = False
    with open(map_path) as f:
        for line in f:
            if line.startswith("Linker script and memory map"):
                in_map = True
                continue
            if not in_map:
                continue
            if line.startswith("Cross Reference Table"):
                break
            m = re.match(r"^(\.\S+|/DISCARD/)(\s+0x[0-9a-f]+\s+0x[0-9a-f]+.*)?$", line.rstrip("\n"))
            if m:
                out_sec = m.group(1)
                pending = None
                continue
            m = re.match(r"^ (\S+)\s+0x([0-9a-f]+)\s+0x([0-9a-f]+)\s+(\S.*)$", line.rstrip("\n"))
            if m is None and pending is not None:
                m2 = re.match(r"^\s+0x([0-9a-f]+)\s+0x([0-9a-f]+)\s+(\S.*)$", line.rstrip("\n"))
                if m2:
                    m = (pending, m2.group(1), m2.group(2), m2.group(3))
                pending = None
            elif m is not None:
                m = (m.group(1), m.group(2), m.group(3), m.group(4))
            else:
                m1 = re.match(r"^ (\.\S+|COMMON)$", line.rstrip("\n"))
                pending = m1.group(1) if m1 else None
                continue
            if m is None or out_sec not in wanted:
                continue
            name, _, size, path = m
            size = int(size, 16)
            if size == 0:
                continue
            if name == "*fill*":
                path = "linker fill"
            objects.add(path)
            key = origin(path)
            totals.setdefault(key, {}).setdefault(out_sec, 0)
            totals[key][out_sec] += size
    return totals, objects


# ---------------------------------------------------------------- stack analysis ----------
def ci_file_for(obj, build_dir):
    """The .ci file GCC wrote next to an object of the map ('dir/x.cpp.obj' or 'dir/libN.a(x.cpp.obj)')."""
    m = re.match(r"^(.*?)lib([^/()]+)\.a\((.+)\)$", obj)
    if m:
        base = os.path.join(build_dir, m.group(1), "CMakeFiles", m.group(2) + ".dir")
        hits = glob.glob(os.path.join(base, "**", re.sub(r"\.obj$|\.o$", "", m.group(3)) + ".ci"), recursive=True)
        return hits[0] if hits else None
    path = os.path.join(build_dir, re.sub(r"\.obj$|\.o$", "", obj) + ".ci")
    return path if os.path.exists(path) else None


def parse_ci(path, nodes, edges):
    text = open(path).read()
    for m in re.finditer(r'node: \{ title: "([^"]+)" label: "([^"]*)"', text):
        title, label = m.group(1), m.group(2)
        s = re.search(r"\\n(\d+) bytes \(([a-z,]+)\)", label)
        if s:
            prev = nodes.get(title)
            frame = int(s.group(1))
            if prev is None or prev["frame"] is None or frame > prev["frame"]:
                nodes[title] = {"frame": frame, "kind": s.group(2), "source": os.path.basename(path),
                                "label": label.split("\\n")[0]}
        elif title not in nodes:
            nodes[title] = {"frame": None, "kind": "external", "source": None, "label": label.split("\\n")[0]}
    for m in re.finditer(r'edge: \{ sourcename: "([^"]+)" targetname: "([^"]+)"', text):
        edges.setdefault(m.group(1), set()).add(m.group(2))


def disassembly(objdump, image):
    """function -> (frame bytes upper bound, callees, has_indirect, dynamic) from the image."""
    funcs, cur = {}, None
    addr_names = {}
    for line in run([objdump, "-d", "--no-show-raw-insn", image]).splitlines():
        m = re.match(r"^([0-9a-f]+) <([^>]+)>:$", line)
        if m:
            cur = m.group(2)
            funcs[cur] = {"frame": 0, "callees": set(), "indirect": False, "dynamic": False}
            addr_names[int(m.group(1), 16)] = cur
            continue
        if cur is None:
            continue
        m = re.match(r"^\s+[0-9a-f]+:\s+(\S+)\s*(.*)$", line)
        if not m:
            continue
        op, args = m.group(1), m.group(2).split("@")[0].strip()
        f = funcs[cur]
        if op in ("push", "push.w") or (op.startswith("stmdb") and args.startswith("sp!")):
            regs = re.search(r"\{([^}]*)\}", args)
            f["frame"] += 4 * count_regs(regs.group(1)) if regs else 0
        elif op in ("vpush", "vpush.64", "vpush.32") or (op.startswith("vstmdb") and args.startswith("sp!")):
            regs = re.search(r"\{([^}]*)\}", args)
            if regs:
                n = count_regs(regs.group(1))
                f["frame"] += (8 if "d" in regs.group(1) else 4) * n
        elif re.match(r"^sub(s|\.w|w)?$", op) and re.match(r"^sp,\s*(sp,\s*)?#\d+", args):
            f["frame"] += int(re.search(r"#(\d+)", args).group(1))
        elif re.match(r"^sub(s|\.w|w)?$", op) and re.match(r"^sp,\s*(sp,\s*)?r", args):
            f["dynamic"] = True
        elif re.match(r"^str\S*$", op) and re.search(r"\[sp, #-(\d+)\]!", args):
            f["frame"] += int(re.search(r"\[sp, #-(\d+)\]!", args).group(1))
        elif op in ("bl", "blx") and "<" in args:
            f["callees"].add(re.search(r"<([^>+]+)", args).group(1))
        elif op in ("blx",) or (op == "bx" and args != "lr") or (op == "mov" and args.startswith("pc") and args != "pc, lr") \
                or (op.startswith("ldr") and args.startswith("pc") and not re.match(r"^pc,\s*\[sp\]", args)):
            f["indirect"] = True  # a call or jump through a register (ldr pc, [sp], #n is a return)
        elif op in ("b.w", "b") and "<" in args:
            target = re.search(r"<([^>+]+)", args).group(1)
            if target != cur:  # a tail call to another function
                f["callees"].add(target)
    return funcs


def count_regs(text):
    n = 0
    for part in text.split(","):
        part = part.strip()
        m = re.match(r"^([rsd])(\d+)-[rsd](\d+)$", part)
        n += int(m.group(3)) - int(m.group(2)) + 1 if m else (1 if part else 0)
    return n


def init_array_entries(readelf, nm, image, secs):
    if ".init_array" not in secs or secs[".init_array"]["size"] == 0:
        return []
    dump = run([readelf, "-x", ".init_array", image])
    words = []
    for line in dump.splitlines():
        m = re.match(r"^\s+0x[0-9a-f]+ ((?:[0-9a-f]{8} ?){1,4})", line)
        if m:
            for w in m.group(1).split():
                words.append(int.from_bytes(bytes.fromhex(w), "little") & ~1)
    addr = {}
    for line in run([nm, "--defined-only", image]).splitlines():
        p = line.split()
        if len(p) == 3 and p[1] in "tTwW":
            addr[int(p[0], 16) & ~1] = p[2]
    return [addr[w] for w in words if w in addr]


class StackGraph:
    def __init__(self, nodes, edges, disasm, indirect_rules, init_array, in_image):
        self.nodes, self.edges, self.disasm = nodes, edges, disasm
        self.in_image = in_image
        self.indirect_rules = indirect_rules
        self.init_array = init_array
        self.memo = {}
        self.notes = {"recursion": set(), "dynamic": set(), "unresolved_indirect": set(), "from_disassembly": set(),
                      "unknown": set(), "absent": set()}
        # Global functions appear as "name" in callers and "file:name" for local definitions.
        self.by_name = {}
        for title in nodes:
            self.by_name.setdefault(title.split(":")[-1], []).append(title)

    def resolve_indirect(self, caller):
        for pattern_caller, regex in self.indirect_rules:
            if re.search(pattern_caller, caller):
                return [t for t in self.all_functions() if re.search(regex, t)]
        self.notes["unresolved_indirect"].add(caller)
        return []

    def all_functions(self):
        return set(t for t, n in self.nodes.items() if n["frame"] is not None) | set(self.disasm)

    def cost(self, fn, stack=()):
        if fn in self.memo:
            return self.memo[fn]
        if fn in stack:
            self.notes["recursion"].add(fn)
            return 0, [fn + " (recursion)"]
        stack = stack + (fn,)
        node = self.nodes.get(fn)
        if node is None or node["frame"] is None:
            # A global called by its bare name, defined under "file:name"; or a complete-object
            # constructor/destructor (C1/D1) that GCC emits as an alias of the base one (C2/D2).
            bare = fn.split(":")[-1]
            candidates = [bare]
            for marker in ("C1E", "D1E"):
                i = bare.rfind(marker)
                if i > 0:
                    candidates.append(bare[:i] + marker[0] + "2E" + bare[i + 3:])
            defined = [t for c in candidates for t in self.by_name.get(c, []) if self.nodes[t]["frame"] is not None]
            if defined:
                result = max((self.cost(t, stack[:-1]) for t in defined if t != fn), key=lambda x: x[0],
                             default=(0, []))
                self.memo[fn] = result
                return result
        if node is not None and node["frame"] is not None:
            frame = node["frame"]
            if node["kind"] != "static":
                self.notes["dynamic"].add(f"{fn} ({node['kind']})")
            callees = set(self.edges.get(fn, ()))
            if "__indirect_call" in callees:
                callees.discard("__indirect_call")
                callees |= set(self.resolve_indirect(fn))
        elif fn in self.disasm:
            d = self.disasm[fn]
            self.notes["from_disassembly"].add(fn)
            frame = d["frame"]
            if d["dynamic"]:
                self.notes["dynamic"].add(f"{fn} (disassembly)")
            callees = set(d["callees"])
            if d["indirect"]:
                if fn == "__libc_init_array":
                    callees |= set(self.init_array)
                else:
                    callees |= set(self.resolve_indirect(fn))
        elif fn not in self.in_image:
            # An edge of a .ci file to a function the image does not contain: the call was
            # optimised away after the call graph was written (e.g. a signed 64-bit division
            # that became unsigned); nothing to count.
            self.notes["absent"].add(fn)
            frame, callees = 0, set()
        else:
            self.notes["unknown"].add(fn)
            frame, callees = 0, set()
        best, best_path = 0, []
        for c in sorted(callees):
            cc, cp = self.cost(c, stack)
            if cc > best:
                best, best_path = cc, cp
        result = (frame + best, [f"{fn} [{frame}]"] + best_path)
        self.memo[fn] = result
        return result


def demangle(names):
    try:
        out = run(["c++filt"] + names).splitlines()
        return out if len(out) == len(names) else names
    except (OSError, RuntimeError):
        return names


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--image", required=True)
    ap.add_argument("--map", required=True)
    ap.add_argument("--build-dir", required=True)
    ap.add_argument("--tools-prefix", default="arm-none-eabi-")
    ap.add_argument("--entry", action="append", default=[], help="NAME=SYMBOL")
    ap.add_argument("--isr", action="append", default=[])
    ap.add_argument("--exception-frame", type=int, default=108)
    ap.add_argument("--indirect", action="append", default=[], help="CALLER_REGEX=TARGET_REGEX")
    ap.add_argument("--stack-check", help="entry NAME whose worst case (+ interrupts) is held to --limit-stack")
    ap.add_argument("--limit-flash", type=int)
    ap.add_argument("--limit-flash-scope", choices=["with-data", "without-data"], default="without-data")
    ap.add_argument("--limit-ram", type=int)
    ap.add_argument("--limit-stack", type=int)
    ap.add_argument("--json")
    a = ap.parse_args()
    t = a.tools_prefix
    try:
        secs = sections(t + "readelf", a.image)
        sizes = symbol_sizes(t + "nm", a.image)
        flash = sum(secs[s]["size"] for s in FLASH_SECTIONS if s in secs)
        ram = sum(secs[s]["size"] for s in RAM_SECTIONS if s in secs)
        data = sum(v for k, v in sizes.items() if k.startswith(REPLAY_DATA_PREFIX))
        origins, objects = map_origins(a.map, set(FLASH_SECTIONS) | set(RAM_SECTIONS))
        nodes, edges, missing_ci = {}, {}, []
        for obj in sorted(objects):
            if obj == "linker fill" or "arm-none-eabi" in obj:
                continue
            ci = ci_file_for(obj, a.build_dir)
            if ci:
                parse_ci(ci, nodes, edges)
            else:
                missing_ci.append(obj)
        disasm = disassembly(t + "objdump", a.image)
        # Aliases (printf = iprintf in newlib-nano, ...): objdump labels an address with one name.
        addresses = symbol_addresses(t + "nm", a.image)
        label_at = {}
        for name, adr in addresses.items():
            if name in disasm:
                label_at.setdefault(adr, name)
        for name, adr in addresses.items():
            if name not in disasm and adr in label_at:
                disasm[name] = disasm[label_at[adr]]
        rules = [tuple(r.split("=", 1)) for r in a.indirect]
        in_image = set(sizes) | set(disasm)
        graph = StackGraph(nodes, edges, disasm, rules, init_array_entries(t + "readelf", t + "nm", a.image, secs),
                           in_image)
    except (OSError, RuntimeError, ValueError) as e:
        print(f"footprint: {e}", file=sys.stderr)
        return 2

    res = {"image": a.image, "flash_bytes": flash, "flash_without_replay_data_bytes": flash - data,
           "replay_data_bytes": data, "static_ram_bytes": ram,
           "sections": {k: v["size"] for k, v in secs.items() if k in FLASH_SECTIONS + RAM_SECTIONS + (".heap", ".stack")},
           "by_origin": origins, "stack": {}, "objects_without_ci": missing_ci}
    print(f"footprint: {a.image}")
    print(f"  flash {flash} B ({flash / 1024:.1f} KiB); without the replay data {flash - data} B "
          f"({(flash - data) / 1024:.1f} KiB); replay data {data} B")
    print(f"  static RAM (.data + .bss + .noinit) {ram} B ({ram / 1024:.1f} KiB); linker-script reservations: "
          f"heap {secs.get('.heap', {}).get('size', 0)} B (libc only), stack {secs.get('.stack', {}).get('size', 0)} B")
    print("  by origin (flash = code + read-only + .data init; RAM = .data + .bss + .noinit):")
    for key in sorted(origins):
        v = origins[key]
        fl = sum(n for s, n in v.items() if s in FLASH_SECTIONS)
        rm = sum(n for s, n in v.items() if s in RAM_SECTIONS)
        print(f"    {key:62s} flash {fl:8d}  RAM {rm:6d}")

    isr_cost, isr_path = 0, []
    for isr in a.isr:
        c, p = graph.cost(isr)
        if c > isr_cost:
            isr_cost, isr_path = c, p
    failures = []
    for spec in a.entry:
        name, sym = spec.split("=", 1)
        c, path = graph.cost(sym)
        entry = {"symbol": sym, "worst_bytes": c, "path": demangle(path)}
        if name == a.stack_check:
            entry["isr_bytes"] = isr_cost
            entry["isr_path"] = demangle(isr_path)
            entry["exception_frame_bytes"] = a.exception_frame
            entry["total_bytes"] = c + (isr_cost + a.exception_frame if a.isr else 0)
        res["stack"][name] = entry
        print(f"  worst-case stack from {name}: {c} B" +
              (f"; with the interrupt ({isr_cost} B + {a.exception_frame} B exception frame): {entry['total_bytes']} B"
               if "total_bytes" in entry else ""))
        for step in entry["path"]:
            print(f"      {step[:150]}")
    notes = {k: sorted(v) for k, v in graph.notes.items()}
    res["stack_notes"] = notes
    if notes["from_disassembly"]:
        print(f"  from the disassembly (library code, no .ci): {', '.join(notes['from_disassembly'])}")
    for k in ("recursion", "dynamic", "unresolved_indirect", "unknown", "absent"):
        if notes[k]:
            print(f"  {k}: {', '.join(demangle(notes[k]))}")
    if missing_ci:
        print(f"  objects without a .ci file: {', '.join(missing_ci)}")
    complete = not (notes["recursion"] or notes["dynamic"] or notes["unresolved_indirect"] or notes["unknown"])
    res["stack_bound_complete"] = complete

    flash_checked = flash - data if a.limit_flash_scope == "without-data" else flash
    if a.limit_flash is not None and flash_checked > a.limit_flash:
        failures.append(f"flash {flash_checked} B > {a.limit_flash} B")
    if a.limit_ram is not None and ram > a.limit_ram:
        failures.append(f"static RAM {ram} B > {a.limit_ram} B")
    if a.limit_stack is not None and a.stack_check:
        e = res["stack"].get(a.stack_check)
        if e is None:
            failures.append(f"no --entry {a.stack_check}")
        else:
            if e["total_bytes"] > a.limit_stack:
                failures.append(f"worst-case stack {e['total_bytes']} B > {a.limit_stack} B")
            if not complete:
                failures.append("the stack bound is incomplete (see the notes above)")
    res["limits"] = {"flash": a.limit_flash, "flash_scope": a.limit_flash_scope, "ram": a.limit_ram,
                     "stack": a.limit_stack}
    res["failures"] = failures
    if a.json:
        with open(a.json, "w") as f:
            json.dump(res, f, indent=1)
    for m in failures:
        print(f"footprint: FAIL: {m}")
    if not failures and (a.limit_flash or a.limit_ram or a.limit_stack):
        print("footprint: within the limits")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
