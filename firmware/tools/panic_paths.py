#!/usr/bin/env python3
"""No reachable panic path in the control loop: walks the call graph of the firmware ELF from the
given roots (default: the sampling interrupt ADC and the console interrupt USART2) through every
direct branch (bl / b.w / b / blx imm / cbz / cbnz) and fails if any reached function is a panic
entry point (core::panicking::*, panic_fmt, *_failed, rust_begin_unwind, ...).

Usage: panic_paths.py ELF [ROOT ...]   (needs llvm-objdump and llvm-nm)
A ROOT starting with `~` is a regular expression over the (demangled) function names.
Indirect calls (blx rN, function pointers, e.g. core::fmt's trait objects) are not followed; the
reached functions that make such calls are listed so that they can be reviewed.
"""
import bisect
import re
import subprocess
import sys
from collections import deque

PANIC = re.compile(r"panic|_failed\b|rust_begin_unwind|unwrap_failed|expect_failed|abort")


def main():
    if len(sys.argv) < 2:
        print(__doc__)
        return 2
    elf = sys.argv[1]
    roots = sys.argv[2:] or ["ADC", "USART2"]
    syms = subprocess.run(
        ["llvm-nm", "-n", "-S", "--defined-only", "-C", elf],
        check=True, capture_output=True, text=True,
    ).stdout
    funcs = []  # (start, end, name), Thumb bit cleared
    for line in syms.splitlines():
        parts = line.split(" ", 3)
        if len(parts) == 4 and parts[2] in ("t", "T"):
            start = int(parts[0], 16) & ~1
            funcs.append((start, start + int(parts[1], 16), parts[3]))
    funcs.sort()
    starts = [f[0] for f in funcs]

    def owner(addr):
        i = bisect.bisect_right(starts, addr) - 1
        if i >= 0 and funcs[i][0] <= addr < max(funcs[i][1], funcs[i][0] + 1):
            return funcs[i][2]
        return None

    dis = subprocess.run(
        ["llvm-objdump", "-d", "--no-show-raw-insn", "-C", elf],
        check=True, capture_output=True, text=True,
    ).stdout
    insn = re.compile(r"^\s*([0-9a-f]+):\s+(\S+)\s+(.*)$")
    target = re.compile(r"0x([0-9a-f]+)")
    direct = {"bl", "blx", "b", "b.w", "b.n", "cbz", "cbnz"}
    calls, indirect_callers = {name: set() for _, _, name in funcs}, set()
    for line in dis.splitlines():
        m = insn.match(line)
        if not m:
            continue
        addr, op, rest = int(m.group(1), 16), m.group(2), m.group(3)
        f = owner(addr)
        if f is None:
            continue
        cond_branch = op.startswith("b") and len(op.split(".")[0]) == 3 and op not in ("bic", "bfi", "bfc", "bkpt")
        if op in direct or cond_branch:
            t = target.search(rest)
            if t:
                g = owner(int(t.group(1), 16))
                if g and g != f:
                    calls[f].add(g)
            elif op in ("blx", "bx") and not rest.startswith("lr"):
                indirect_callers.add(f)
        elif op in ("blx", "bx") and not rest.startswith("lr"):
            indirect_callers.add(f)
    # A root starting with `~` is a regular expression over function names: the targets of the
    # indirect calls (e.g. `~as core::fmt::(Display|Write)>` for the formatting trait objects).
    expanded = []
    for r in roots:
        if r.startswith("~"):
            expanded += [f for f in calls if re.search(r[1:], f)]
        else:
            expanded.append(r)
    seen, parent = set(), {}
    queue = deque(r for r in expanded if r in calls)
    missing = [r for r in expanded if r not in calls]
    if missing:
        print(f"error: roots not found in {elf}: {missing}")
        return 2
    seen.update(queue)
    while queue:
        f = queue.popleft()
        for g in calls.get(f, ()):
            if g not in seen:
                seen.add(g)
                parent[g] = f
                queue.append(g)
    bad = sorted(f for f in seen if PANIC.search(f))
    print(f"{len(seen)} functions reachable from {len(expanded)} roots ({', '.join(roots)}) by direct branches")
    for f in sorted(seen & indirect_callers):
        print(f"  indirect call in: {f}")
    if bad:
        for f in bad:
            chain, g = [f], f
            while g in parent:
                g = parent[g]
                chain.append(g)
            print("PANIC PATH: " + " <- ".join(chain))
        return 1
    print("no panic entry point reachable")
    return 0


if __name__ == "__main__":
    sys.exit(main())
