"""Command line: `python -m metacell_tools.fwcheck report|size|vectors|ticks|golden-header|lint|irq|cpu-budget`.

report         soft-float check, division check, code size, QEMU bit-exact count, instructions/tick
size           code size of the cross-compiled library
vectors        QEMU golden vectors against the host build
ticks          instructions per mc_cell_tick under QEMU (median/max per class)
profile [-v]   where the instructions of one enabled tick go (per function; -v: trace)
golden-header  regenerate test/test_native_vectors/golden_vectors.h from the host build
lint --elf F   soft-float/division helpers reachable from the control path of a linked image
cpu-budget     worst-case cycles of the cell's interrupts (tick, encoder edges) in its linked image
irq --elf F    interrupt map of a linked image: vector table, fault entry and record, the cell's priorities
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

from metacell_common.outpaths import check_out_file

from . import armbuild, cpubudget, golden, irqmap, qemu
from .cpubudget import BUDGET_LIMIT
from .qemu import DEFAULT_SEED


def _softfloat(objs) -> bool:
    bad = armbuild.softfloat_violations(objs)
    print("soft-float helpers in the library: " + ("none" if not bad else str(bad)))
    return not bad


def _division(objs) -> bool:
    rep = armbuild.division_check(objs)
    print(
        f"division helpers reachable from {', '.join(armbuild.CONTROL_ROOTS)}: "
        + ("none" if not rep.violations else "")
    )
    for chain in rep.violations:
        print("  " + " -> ".join(chain))
    if rep.indirect:
        print("  unresolved indirect calls in: " + ", ".join(rep.indirect))
    print(f"  ({len(rep.reachable)} functions on the control path: {', '.join(rep.reachable)})")
    return rep.ok


def _size(objs) -> None:
    print("code size of lib/metacell (arm-none-eabi-gcc -Os, cortex-m0plus, bytes):")
    print(armbuild.format_size(armbuild.code_size(objs)))


def _vectors(seed: int) -> bool:
    c = qemu.golden_compare(seed)
    print(
        f"QEMU golden vectors (seed {seed:#x}): {c.identical}/{c.n_host} bit-identical, "
        f"target reported {c.n_target}, checksum host {c.fnv_host:#010x} "
        f"target {c.fnv_target:#010x}"
    )
    if c.first_mismatch:
        print(c.first_mismatch)
    return c.ok


def _variant(lib_src, cflags):
    """(objects, bench ELF or None) for a variant library / flags, or the real one."""
    if not lib_src and not cflags:
        return armbuild.library_objects(), None
    src = Path(lib_src).resolve() if lib_src else armbuild.LIB_SRC
    flags = [f for f in armbuild.CFLAGS if f != "-Os"] + (cflags.split() if cflags else ["-Os"])
    objs = armbuild.library_objects(src, flags)
    return objs, qemu.build_image("bench", lib_objs=objs, lib_src=src)


def _profile(elf, verbose: bool) -> None:
    total, per, lines = qemu.tick_profile(elf)
    print(f"one enabled, fault-free tick with a perturbation: {total} instructions")
    for name, n in per:
        print(f"  {name:<24}{n:>5}")
    if verbose:
        print("\n".join(lines))


def _ticks(elf=None) -> bool:
    s = qemu.tick_stats(elf)
    calib_ok = s.calibration == s.expected
    print(
        f"instruction counter calibration: {s.calibration} expected {s.expected} " + ("ok" if calib_ok else "MISMATCH")
    )
    print("instructions per mc_cell_tick (both motors), Cortex-M0 under QEMU:")
    for name, (med, mx, n) in s.summary().items():
        print(f"  {name:<50} median {med:>6g}  max {mx:>5}  ({n} ticks)")
    print(
        f"  mc_quad_update (per edge, ISR): median {sorted(s.quad_update)[len(s.quad_update) // 2]}"
        f", max {max(s.quad_update)}; mc_quad_snapshot: {max(s.snapshot)}"
    )
    worst = max(s.select(**qemu.BUDGET_CASE))
    print(
        f"  budget {qemu.BUDGET} (every tick of the default configuration, worst {worst}): "
        + ("within" if worst <= qemu.BUDGET else "OVER")
    )
    worst_b = max(s.select(**qemu.BUDGET_BEMF_CASE))
    print(
        f"  budget {qemu.BUDGET_BEMF} (every tick with back-EMF compensation on, worst {worst_b}): "
        + ("within" if worst_b <= qemu.BUDGET_BEMF else "OVER")
    )
    return calib_ok and worst <= qemu.BUDGET and worst_b <= qemu.BUDGET_BEMF


def _lint(elf: str | None, extra_roots: list[str], role: str = "cell") -> int:
    if not elf or not Path(elf).is_file():
        print(f"fwcheck lint: --elf must name a linked image (got {elf!r})", file=sys.stderr)
        return 2
    base = armbuild.PRIMARY_ROOTS if role == "primary" else armbuild.CONTROL_ROOTS
    rep = armbuild.lint_elf(Path(elf), tuple(base) + tuple(extra_roots))
    if not rep.roots:
        print(f"fwcheck lint: none of the {role}'s entry points ({', '.join(base)}) is in {elf}")
        return 1
    print(f"fwcheck lint {elf}: roots {', '.join(rep.roots)}")
    for kind, chains in (("soft-float", rep.softfloat), ("division", rep.division)):
        print(f"  {kind} helpers on the control path: " + ("none" if not chains else ""))
        for c in chains:
            print("    " + " -> ".join(c))
    if rep.indirect:
        print("  unresolved indirect calls in: " + ", ".join(rep.indirect))
    return 0 if rep.ok else 1


def _irq(elf: str | None, role: str) -> int:
    if not elf or not Path(elf).is_file():
        print(f"fwcheck irq: --elf must name a linked image (got {elf!r})", file=sys.stderr)
        return 2
    try:
        rep = irqmap.check(Path(elf), role)
    except irqmap.ImageError as e:
        print(f"fwcheck irq: {e}", file=sys.stderr)
        return 2
    print(irqmap.format_report(rep, elf))
    return 0 if rep.ok else 1


def _cpu_budget(elf: str | None, limit: float) -> int:
    path = Path(elf) if elf else cpubudget.DEFAULT_ELF
    if not path.is_file():
        print(
            f"fwcheck cpu-budget: no linked image at {path} (build it with `pio run -e cell`, or pass --elf)",
            file=sys.stderr,
        )
        return 2
    try:
        image = cpubudget.parse_disassembly(cpubudget.disassemble(path))
        b = cpubudget.cell_budget(image, priorities=irqmap.effective_priorities(path))
        core = cpubudget.cell_budget(image, cpubudget.CORE_ONLY)
    except (cpubudget.AnalysisError, cpubudget.UnsupportedInsn, irqmap.ImageError) as e:
        print(f"fwcheck cpu-budget: {e}", file=sys.stderr)
        return 2
    print(cpubudget.format_budget(b, str(path)))
    print(f"  (core timings only, zero-wait memory: total {core.total:.1%})")
    ok = b.total <= limit
    print(f"  limit {limit:.0%}: " + ("within" if ok else "OVER"))
    responses_ok = all(r.ok for r in b.responses)
    print("  responses: " + ("within their deadlines" if responses_ok else "OVER"))
    return 0 if ok and responses_ok else 1


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m metacell_tools.fwcheck",
        description=__doc__,
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
        "  python -m metacell_tools.fwcheck report                     # every check, as in the README table\n"
        "  python -m metacell_tools.fwcheck ticks --cflags -O2         # instructions per tick at another -O\n"
        "  python -m metacell_tools.fwcheck profile -v\n"
        "  python -m metacell_tools.fwcheck lint --elf .pio/build/cell/firmware.elf --role cell\n"
        "  python -m metacell_tools.fwcheck cpu-budget --elf .pio/build/cell/firmware.elf\n"
        "  python -m metacell_tools.fwcheck irq --elf .pio/build/primary/firmware.elf --role primary",
    )
    ap.add_argument(
        "command",
        nargs="?",
        default="report",
        choices=["report", "size", "vectors", "ticks", "golden-header", "lint", "profile", "cpu-budget", "irq"],
        help="what to check (default report; each is described above)",
    )
    ap.add_argument("--lib-src", help="ticks/profile/size: measure a variant copy of lib/metacell/src")
    ap.add_argument("--cflags", help="ticks/profile/size: optimisation flags instead of -Os")
    ap.add_argument("-v", "--verbose", action="store_true", help="profile: print the trace")
    ap.add_argument("--elf", help="lint, irq: linked image to check; cpu-budget: cell image (default .pio/build/cell)")
    ap.add_argument(
        "--limit",
        type=float,
        default=None,
        help="cpu-budget: largest allowed fraction of the 48 MHz CPU for the interrupts (default 0.5)",
    )
    ap.add_argument("--root", action="append", help="lint: extra control-path entry point")
    ap.add_argument(
        "--role",
        choices=("cell", "primary"),
        default="cell",
        help="lint, irq: which image (lint: cell = the control path, primary = poll and SLCAN; irq: its handlers)",
    )
    ap.add_argument(
        "--seed",
        type=lambda s: int(s, 0),
        default=None,
        help="vectors/report: seed of the golden-vector generator (decimal or 0x...; default: the fixed one)",
    )
    ap.add_argument("--out", help="golden-header: output path")
    a = ap.parse_args(argv)
    if a.limit is not None and not (math.isfinite(a.limit) and 0 < a.limit <= 1):
        print(f"fwcheck: --limit {a.limit}: expected a fraction of the CPU in (0, 1]", file=sys.stderr)
        return 2
    try:
        if a.command == "golden-header":
            problem = check_out_file(a.out, "--out") if a.out else None
            if problem:
                print(f"fwcheck: {problem}", file=sys.stderr)
                return 2

            path = golden.write_header(a.out)
            print(f"wrote {path}")
            return 0
        if a.command == "lint":
            return _lint(a.elf, a.root or [], a.role)
        if a.command == "irq":
            return _irq(a.elf, a.role)
        if a.command == "cpu-budget":
            return _cpu_budget(a.elf, BUDGET_LIMIT if a.limit is None else a.limit)
        objs, bench_elf = _variant(a.lib_src, a.cflags)
        if a.command == "profile":
            _profile(bench_elf, a.verbose)
            return 0
        ok = True
        if a.command in ("report", "size"):
            if a.command == "report":
                ok &= _softfloat(objs)
                ok &= _division(objs)
            _size(objs)
        if a.command in ("report", "vectors"):
            ok &= _vectors(a.seed if a.seed is not None else DEFAULT_SEED)
        if a.command in ("report", "ticks"):
            ok &= _ticks(bench_elf)
    except armbuild.ToolError as e:
        print(f"fwcheck: {e}", file=sys.stderr)
        return 2
    return 0 if ok else 1


if __name__ == "__main__":
    sys.exit(main())
