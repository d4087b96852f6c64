"""Cross-build the cell library for the Cortex-M0+ and check it: soft-float, division reachability, size.

The library is compiled exactly as the boards need it (Debian ``arm-none-eabi-gcc``,
``-mcpu=cortex-m0plus -mthumb -Os``), one object per source file. The checks read
those objects with binutils:

* soft float: the undefined symbols of every object (``nm -u``) against the
  EABI/libgcc floating-point helper names;
* division: a call graph built from the relocations in ``objdump -dr`` (calls,
  branches and literal-pool addresses of functions), walked from the control-path
  entry points; any reachable division helper is reported with the call chain.
  Indirect calls in reachable code cannot be resolved and are reported too.
"""

from __future__ import annotations

import hashlib
import os
import re
import shutil
import tempfile
from collections.abc import Iterable
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path

from metacell_common.target.toolchain import ToolError
from metacell_common.target.toolchain import run as _run

ROOT = Path(__file__).resolve().parents[2]
LIB_SRC = ROOT / "lib" / "metacell" / "src"
BUILD_ROOT = Path(os.environ.get("FWCHECK_BUILD_DIR", ROOT / "build" / "fwcheck"))

CC = "arm-none-eabi-gcc"
CPU_FLAGS = ["-mcpu=cortex-m0plus", "-mthumb"]
CFLAGS = CPU_FLAGS + [
    "-Os",
    "-std=c99",
    "-pedantic",
    "-ffunction-sections",
    "-fdata-sections",
    "-Wall",
    "-Wextra",
    "-Werror",
]

#: Control-path entry points: the tick and the decoder ISR/snapshot.
# The tick inlines the law, velocity and drive; their public wrappers are control
# path too (the emulator and tests call them), so they are roots of their own.
# The primary's steady path (poll scheduler, bus results, SLCAN in and out): no control law, but it runs
# every cycle on the same divider-less core, so it is held to the same rule.
PRIMARY_ROOTS = (
    "mc_primary_next",
    "mc_primary_complete",
    "mc_primary_can_rx",
    "mc_primary_pop",
    "mc_primary_ms",
    "mc_slcan_rx",
    "mc_slcan_encode",
)
CONTROL_ROOTS = (
    "mc_cell_tick",
    "mc_quad_update",
    "mc_quad_snapshot",
    "mc_reaction_eval",
    "mc_psi_prime",
    "mc_drive_command",
    "mc_vel_update",
)

SOFTFLOAT_RE = re.compile(
    r"^(__aeabi_(f|d|cf|cd|[iu]?l?2[fd]|ul2[fd])\w*"
    r"|__(add|sub|mul|div|neg|pow)[sdtx]f3"
    r"|__(fix|fixuns)[sdtx]f[sdt]i|__float(un)?[sdt]i[sdtx]f"
    r"|__(extend|trunc)[sdtx]f[sdtx]f2|__(eq|ne|lt|le|gt|ge|unord|cmp)[sdtx]f2)$"
)
DIVISION_RE = re.compile(
    r"^(__aeabi_u?idiv(mod)?|__aeabi_u?ldivmod|__u?(div|mod)[sdt]i3|__udivmod[sdt]i4"
    r"|__divmod[sdt]i4|__gnu_u?ldivmod_helper)$"
)


def library_sources() -> list[Path]:
    return sorted(LIB_SRC.rglob("*.c"))


def _digest(paths: list[Path], extra: list[str]) -> str:
    h = hashlib.sha256()
    for p in paths:
        h.update(str(p).encode())
        h.update(p.read_bytes())
    h.update(" ".join(extra).encode())
    return h.hexdigest()[:16]


def compile_objects(
    sources: list[Path], outdir: Path, flags: list[str] | None = None, include_dirs: list[Path] | None = None
) -> list[Path]:
    """Compile each source to outdir/<stem>.o; returns the object paths."""
    outdir.mkdir(parents=True, exist_ok=True)
    incs = [f"-I{d}" for d in (include_dirs or [LIB_SRC])]
    objs = []
    for src in sources:
        obj = outdir / (src.stem + (".S.o" if src.suffix == ".S" else ".o"))
        _run([CC, *(flags if flags is not None else CFLAGS), *incs, "-c", str(src), "-o", str(obj)])
        objs.append(obj)
    return objs


def _publish(build, key: str, name: str) -> Path:
    """Build into a private temp dir, then publish atomically under BUILD_ROOT/name-key
    (parallel test workers may race; the loser's copy is discarded)."""
    final = BUILD_ROOT / f"{name}-{key}"
    if (final / ".done").exists():
        return final
    BUILD_ROOT.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{name}-", dir=BUILD_ROOT))
    try:
        build(tmp)
        (tmp / ".done").write_text("ok\n")
        try:
            os.rename(tmp, final)
        except OSError:
            if not (final / ".done").exists():
                raise
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return final


def library_objects(src_dir: Path = LIB_SRC, cflags: list[str] | None = None) -> list[Path]:
    """The cross-compiled library objects (cached by a hash of the sources and flags).
    src_dir/cflags exist for experiments (e.g. measuring a variant of the library)."""
    cflags = CFLAGS if cflags is None else cflags
    srcs = sorted(src_dir.rglob("*.c"))
    headers = sorted(src_dir.rglob("*.h"))
    key = _digest(srcs + headers, cflags)

    def build(tmp: Path) -> None:
        # flatten names: sources in different folders never share a stem here
        stems = [s.stem for s in srcs]
        if len(set(stems)) != len(stems):
            raise ToolError("two library sources share a file name; objects would collide")
        compile_objects(srcs, tmp, cflags, [src_dir])

    d = _publish(build, key, "lib")
    return [d / (s.stem + ".o") for s in srcs]


# --------------------------------------------------------------------------- soft float


def undefined_symbols(obj: Path) -> list[str]:
    out = _run(["arm-none-eabi-nm", "-u", str(obj)])
    return [ln.split()[-1] for ln in out.splitlines() if ln.strip()]


def softfloat_violations(objs: list[Path]) -> dict[str, list[str]]:
    """{object name: [soft-float helpers it references]} (empty dict = clean)."""
    bad = {}
    for o in objs:
        syms = [s for s in undefined_symbols(o) if SOFTFLOAT_RE.match(s)]
        if syms:
            bad[o.name] = sorted(syms)
    return bad


# --------------------------------------------------------------------------- call graph

_SECTION = re.compile(r"^Disassembly of section (\S+):$")
_LABEL = re.compile(r"^([0-9a-f]+) <(.+)>:$")
_RELOC = re.compile(r"^\s+[0-9a-f]+:\s+(R_ARM_\w+)\s+(\S+?)(?:\+0x[0-9a-f]+)?$")
_INDIRECT = re.compile(r"^\s+[0-9a-f]+:\s+[0-9a-f ]+\s+(blx|bx)\s+(r\d+|ip|sl|fp)\b")
_CODE_RELOCS = {
    "R_ARM_THM_CALL",
    "R_ARM_THM_JUMP24",
    "R_ARM_THM_JUMP11",
    "R_ARM_THM_JUMP8",
    "R_ARM_THM_JUMP19",
    "R_ARM_CALL",
    "R_ARM_JUMP24",
    "R_ARM_ABS32",
    "R_ARM_THM_PC22",
}


@dataclass
class CallGraph:
    """Functions of a set of objects and what each one references."""

    edges: dict[str, set[str]] = field(default_factory=dict)  # node -> callees
    indirect: dict[str, int] = field(default_factory=dict)  # node -> indirect calls
    defined: dict[str, str] = field(default_factory=dict)  # node -> object name

    def reachable(self, roots: list[str] | tuple[str, ...]) -> dict[str, list[str]]:
        """Every node reachable from the roots, with one call chain leading to it."""
        missing = [r for r in roots if r not in self.edges]
        if missing:
            raise KeyError(f"entry point(s) not defined in the objects: {missing}")
        paths: dict[str, list[str]] = {}
        stack = [(r, [r]) for r in roots]
        while stack:
            node, path = stack.pop()
            if node in paths:
                continue
            paths[node] = path
            for callee in sorted(self.edges.get(node, ())):
                if callee not in paths:
                    stack.append((callee, path + [callee]))
        return paths


def _display(node: str) -> str:
    return node.split(":", 1)[1] if ":" in node else node


def _node_name(obj: str, file_local: set[str], name: str) -> str:
    """Graph node of a symbol: file-local functions are qualified by their object file, others are global."""
    return f"{obj}:{name}" if name in file_local else name


def call_graph(objs: list[Path]) -> CallGraph:
    g = CallGraph()
    per_obj = []
    global_defs: set[str] = set()
    for o in objs:
        syms = _run(["arm-none-eabi-nm", str(o)])
        glob: set[str] = set()
        local: set[str] = set()
        for ln in syms.splitlines():
            parts = ln.split()
            if len(parts) == 3 and parts[1] in "TtWw":
                (glob if parts[1] in "TW" else local).add(parts[2])
        global_defs |= glob
        per_obj.append((o, glob, local, _run(["arm-none-eabi-objdump", "-dr", str(o)])))

    for o, glob, local, dis in per_obj:
        sec_first: dict[str | None, str] = {}  # section name -> its first function
        raw: list[tuple[str, str]] = []  # (function, reloc target) in this object
        indirect: dict[str, int] = {}
        section = None
        func = None
        for ln in dis.splitlines():
            m = _SECTION.match(ln)
            if m:
                section, func = m.group(1), None
                continue
            m = _LABEL.match(ln)
            if m:
                func = m.group(2)
                sec_first.setdefault(section, func)
                continue
            if func is None:
                continue
            m = _RELOC.match(ln)
            if m and m.group(1) in _CODE_RELOCS:
                raw.append((func, m.group(2)))
                continue
            m = _INDIRECT.match(ln)
            if m and m.group(2) != "lr":
                indirect[func] = indirect.get(func, 0) + 1

        node = partial(_node_name, o.name, local - glob)
        for name in glob | local:
            g.edges.setdefault(node(name), set())
            g.defined[node(name)] = o.name
        for fn, cnt in indirect.items():
            g.indirect[node(fn)] = cnt
        for fn, target in raw:
            if target in sec_first:  # section symbol: .text.<fn>
                target = sec_first[target]
            elif target.startswith("."):
                continue  # data section (tables, constants)
            if target in local or target in glob:
                tnode = node(target)
            elif target in global_defs:
                tnode = target
            elif target.startswith("__") or target in ("memset", "memcpy", "memmove"):
                tnode = target  # external helper (libgcc/libc)
            else:
                tnode = target  # other external symbol (data or code)
            if tnode != node(fn):
                g.edges.setdefault(node(fn), set()).add(tnode)
    return g


@dataclass
class DivisionReport:
    reachable: list[str]
    violations: list[list[str]]  # call chains ending in a division helper
    indirect: list[str]  # reachable functions with unresolved indirect calls

    @property
    def ok(self) -> bool:
        return not self.violations and not self.indirect


def division_check(objs: list[Path], roots: Iterable[str] = CONTROL_ROOTS) -> DivisionReport:
    g = call_graph(objs)
    paths = g.reachable(list(roots))
    viol = [[_display(n) for n in p] for name, p in sorted(paths.items()) if DIVISION_RE.match(name)]
    indirect = sorted(_display(n) for n in paths if g.indirect.get(n))
    reach = sorted(_display(n) for n in paths if n in g.defined)
    return DivisionReport(reach, viol, indirect)


# --------------------------------------------------------------------------- size


@dataclass
class SizeRow:
    name: str
    text: int
    data: int
    bss: int


def code_size(objs: list[Path]) -> list[SizeRow]:
    """Berkeley sizes per object plus a final 'total' row."""
    out = _run(["arm-none-eabi-size", "-t", *map(str, objs)])
    rows = []
    for ln in out.splitlines()[1:]:
        parts = ln.split()
        if len(parts) >= 6:
            name = "total" if "(TOTALS)" in ln else Path(parts[5]).name
            rows.append(SizeRow(name, int(parts[0]), int(parts[1]), int(parts[2])))
    return rows


def format_size(rows: list[SizeRow]) -> str:
    lines = [f"{'object':<16}{'text':>8}{'data':>8}{'bss':>8}"]
    lines += [f"{r.name:<16}{r.text:>8}{r.data:>8}{r.bss:>8}" for r in rows]
    return "\n".join(lines)


# --------------------------------------------------------------------------- linked images

_INSN = re.compile(r"^\s+([0-9a-f]+):\s+([a-z][\w.]*)\s*(.*)$")
_DIRECT = re.compile(r"^(?:0x)?[0-9a-f]+ <([^>+]+)>")


def elf_call_graph(elf: Path) -> CallGraph:
    """Call graph of a linked image from its disassembly: `bl`/`b` to the first
    instruction of another function are edges; `blx`/`bx` through a register
    (other than lr) are indirect calls."""
    dis = _run(["arm-none-eabi-objdump", "-d", "--no-show-raw-insn", str(elf)])
    g = CallGraph()
    func = None
    for ln in dis.splitlines():
        m = _LABEL.match(ln)
        if m:
            func = m.group(2)
            g.edges.setdefault(func, set())
            g.defined[func] = elf.name
            continue
        if func is None:
            continue
        m = _INSN.match(ln)
        if not m:
            continue
        mnem, ops = m.group(2), m.group(3)
        if mnem in ("blx", "bx") and re.match(r"(r\d+|ip|sl|fp)\b", ops) and not ops.startswith("lr"):
            g.indirect[func] = g.indirect.get(func, 0) + 1
        elif mnem.startswith("b"):
            t = _DIRECT.match(ops)
            if t and t.group(1) != func:
                g.edges[func].add(t.group(1))
    return g


@dataclass
class LintReport:
    roots: list[str]
    softfloat: list[list[str]]
    division: list[list[str]]
    indirect: list[str]

    @property
    def ok(self) -> bool:
        return bool(self.roots) and not (self.softfloat or self.division or self.indirect)


def lint_elf(elf: Path, roots: Iterable[str] = CONTROL_ROOTS) -> LintReport:
    """Soft-float or division helpers reachable from the control-path roots of a
    linked image (the Arduino core may use both elsewhere; only reachability counts).
    Roots absent from the image (e.g. inlined) are skipped; none present fails."""
    g = elf_call_graph(elf)
    present = [r for r in roots if r in g.edges]
    paths = g.reachable(present) if present else {}
    sf = [p for n, p in sorted(paths.items()) if SOFTFLOAT_RE.match(n)]
    dv = [p for n, p in sorted(paths.items()) if DIVISION_RE.match(n)]
    ind = sorted(n for n in paths if g.indirect.get(n))
    return LintReport(present, sf, dv, ind)
