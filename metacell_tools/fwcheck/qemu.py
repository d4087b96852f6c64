"""Run the cell library on an emulated Cortex-M0 (QEMU ``microbit``, semihosting): golden vectors and instruction
counts.

Two bare-metal programs are linked with the cross-compiled library objects:

* ``vectors.elf`` runs the shared generator (``csrc/mc_vectors.c``) and streams
  every record to ``vectors.bin`` in QEMU's working directory (SYS_OPEN/SYS_WRITE);
  :func:`golden_compare` runs the same generator on the host against
  ``host_emulator.firmware.load()`` and compares the two streams word for word.
* ``bench.elf`` makes calibration calls of known length and then a representative
  run of ``mc_cell_tick``. QEMU runs it with ``-singlestep -d exec,nochain`` so that
  every guest instruction is its own translation block and each execution is one
  log line; :func:`count_calls` walks that trace and counts the instructions from
  the entry of a function until control is back in its caller.
"""

from __future__ import annotations

import re
import shutil
import statistics
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from . import armbuild, hostvec
from .armbuild import CC, CPU_FLAGS, LIB_SRC, ToolError, _digest, _publish, _run

HERE = Path(__file__).resolve().parent
TARGET = HERE / "target"
CSRC = HERE / "csrc"
QEMU = "qemu-system-arm"
DEFAULT_SEED = 0x2545F491
TRAILER_MAGIC = 0x4D435654
QEMU_TIMEOUT_S = 120

HARNESS_CFLAGS = CPU_FLAGS + [
    "-Os",
    "-std=c99",
    "-pedantic",
    "-ffreestanding",
    "-fno-builtin",
    "-fno-tree-loop-distribute-patterns",
    "-ffunction-sections",
    "-fdata-sections",
    "-Wall",
    "-Wextra",
    "-Werror",
]
LDFLAGS = CPU_FLAGS + ["-nostdlib", "-nostartfiles", "-Wl,--gc-sections"]


def qemu_cmd(elf: Path, extra: list[str] | None = None) -> list[str]:
    return [
        QEMU,
        "-M",
        "microbit",
        "-display",
        "none",
        "-monitor",
        "none",
        "-serial",
        "none",
        "-semihosting-config",
        "enable=on,target=native",
        "-kernel",
        str(elf),
        *(extra or []),
    ]


def build_image(
    kind: str, seed: int = DEFAULT_SEED, lib_objs: list[Path] | None = None, lib_src: Path = LIB_SRC
) -> Path:
    """Link target/main_<kind>.c with the library objects; returns the ELF path (cached)."""
    lib_objs = armbuild.library_objects() if lib_objs is None else lib_objs
    extra = {"vectors": [CSRC / "mc_vectors.c"], "bench": [TARGET / "known.S"]}[kind]
    srcs = [TARGET / "startup.c", TARGET / "semihost.c", TARGET / f"main_{kind}.c", *extra]
    deps = srcs + [TARGET / "link.ld", TARGET / "semihost.h", CSRC / "mc_vectors.h"] + lib_objs
    flags = HARNESS_CFLAGS + [f"-DFW_SEED={seed:#x}u"]
    key = _digest(deps, flags + LDFLAGS)

    def build(tmp: Path) -> None:
        objs = armbuild.compile_objects(srcs, tmp, flags, [lib_src, CSRC, TARGET])
        _run(
            [
                CC,
                *LDFLAGS,
                "-T",
                str(TARGET / "link.ld"),
                "-o",
                str(tmp / f"{kind}.elf"),
                *map(str, objs),
                *map(str, lib_objs),
                "-lgcc",
            ]
        )

    return _publish(build, key, kind) / f"{kind}.elf"


def run_qemu(
    elf: Path, cwd: Path, extra: list[str] | None = None, timeout: float = QEMU_TIMEOUT_S
) -> subprocess.CompletedProcess:
    if shutil.which(QEMU) is None:
        raise ToolError(f"{QEMU} not found: run tools/setup.sh (Debian qemu-system-arm)")
    try:
        p = subprocess.run(qemu_cmd(elf, extra), cwd=cwd, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired as e:
        raise ToolError(f"QEMU did not finish within {timeout} s ({elf.name})") from e
    if p.returncode != 0:
        raise ToolError(f"{elf.name} failed under QEMU (exit {p.returncode}):\n{p.stdout}{p.stderr}")
    return p


# --------------------------------------------------------------------------- golden vectors


@dataclass
class TargetVectors:
    records: np.ndarray  # (N, MCV_WORDS) uint32
    count: int  # record count the target reported
    fnv: int  # target checksum


def target_vectors(seed: int = DEFAULT_SEED) -> TargetVectors:
    elf = build_image("vectors", seed)
    with tempfile.TemporaryDirectory(prefix="fwcheck-q-") as tmp:
        run_qemu(elf, Path(tmp))
        raw = np.fromfile(Path(tmp) / "vectors.bin", dtype="<u4")
    if raw.size < 3 or raw[-3] != TRAILER_MAGIC:
        raise ToolError("vectors.bin from the target has no trailer (run cut short?)")
    body = raw[:-3]
    if body.size % hostvec.WORDS:
        raise ToolError(f"vectors.bin holds {body.size} words, not whole records")
    return TargetVectors(body.reshape(-1, hostvec.WORDS), int(raw[-2]), int(raw[-1]))


@dataclass
class Comparison:
    n_host: int
    n_target: int
    identical: int  # records equal word for word
    first_mismatch: str | None
    fnv_host: int
    fnv_target: int

    @property
    def ok(self) -> bool:
        return self.first_mismatch is None and self.n_host == self.n_target and self.fnv_host == self.fnv_target


def compare_records(host: np.ndarray, target: np.ndarray) -> tuple[int, str | None]:
    n = min(len(host), len(target))
    eq = np.all(host[:n] == target[:n], axis=1)
    identical = int(eq.sum())
    if identical == n and len(host) == len(target):
        return identical, None
    if identical == n:
        return identical, f"record counts differ: host {len(host)}, target {len(target)}"
    i = int(np.argmin(eq))
    return identical, hostvec.describe_mismatch(i, host[i], target[i])


def golden_compare(seed: int = DEFAULT_SEED) -> Comparison:
    tv = target_vectors(seed)
    hv = hostvec.host_vectors(seed)
    identical, first = compare_records(hv.records, tv.records)
    return Comparison(len(hv.records), tv.count, identical, first, hv.fnv, tv.fnv)


# --------------------------------------------------------------------------- instruction counts

_TRACE = re.compile(r"^Trace \d+: 0x[0-9a-f]+ \[[0-9a-f]+/([0-9a-f]+)/")


def symbols(elf: Path) -> dict[str, tuple[int, int]]:
    """Function symbols: name -> (address without the Thumb bit, size)."""
    out = _run(["arm-none-eabi-nm", "-S", "--defined-only", str(elf)])
    syms = {}
    for ln in out.splitlines():
        parts = ln.split()
        if len(parts) == 4 and parts[2] in "Tt":
            syms[parts[3]] = (int(parts[0], 16) & ~1, int(parts[1], 16))
    return syms


def _one_insn_per_tb() -> list[str]:
    """QEMU option for one guest instruction per translation block: `-singlestep`
    up to 8.0 (Debian 12 ships 7.2), `-accel tcg,one-insn-per-tb=on` from 8.1."""
    out = subprocess.run([QEMU, "--version"], capture_output=True, text=True).stdout
    m = re.search(r"version (\d+)\.(\d+)", out)
    if m and (int(m.group(1)), int(m.group(2))) >= (8, 1):
        return ["-accel", "tcg,one-insn-per-tb=on"]
    return ["-singlestep"]


def trace_pcs(elf: Path, timeout: float = QEMU_TIMEOUT_S) -> tuple[np.ndarray, Path]:
    """Run elf one instruction per block and return the executed PCs in order."""
    tmp = Path(tempfile.mkdtemp(prefix="fwcheck-t-"))
    log = tmp / "exec.log"
    try:
        run_qemu(elf, tmp, [*_one_insn_per_tb(), "-d", "exec,nochain", "-D", str(log)], timeout)
        pcs = []
        with open(log) as f:
            for ln in f:
                m = _TRACE.match(ln)
                if m:
                    pcs.append(int(m.group(1), 16))
        return np.asarray(pcs, dtype=np.uint32), tmp
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise


def count_calls(pcs: np.ndarray, func: tuple[int, int], caller: tuple[int, int]) -> list[int]:
    """Instructions per call of `func` made directly from `caller` ((addr, size) each):
    from the first instruction of func up to, not including, the first instruction
    executed back in the caller."""
    entry = func[0]
    lo, hi = caller[0], caller[0] + caller[1]
    in_caller = (pcs >= lo) & (pcs < hi)
    counts = []
    starts = np.nonzero(pcs == entry)[0]
    back = np.nonzero(in_caller)[0]
    for s in starts:
        if s == 0 or not in_caller[s - 1]:
            continue  # entered from elsewhere (not a call from caller)
        k = np.searchsorted(back, s)
        if k == len(back):
            raise ToolError("trace ended inside the measured function")
        counts.append(int(back[k] - s))
    return counts


@dataclass
class TickStats:
    calibration: dict[str, list[int]]  # name -> measured counts
    expected: dict[str, list[int]]
    ticks: list[int]  # per tick, in order
    tags: list[int]  # per tick: enabled|bemf<<1|pert<<2|faults<<16
    quad_update: list[int]
    snapshot: list[int]

    def select(
        self, enabled: bool | None = None, fault: bool | None = None, pert: bool | None = None, bemf: bool | None = None
    ) -> list[int]:
        out = []
        for n, t in zip(self.ticks, self.tags):
            faults = t >> 16
            if bemf is not None and bool(t & 2) != bemf:
                continue
            if enabled is not None and bool(t & 1) != enabled:
                continue
            if fault is not None and bool(faults) != fault:
                continue
            if pert is not None and bool(t & 4) != pert:
                continue
            out.append(n)
        return out

    def summary(self) -> dict[str, tuple[float, int, int]]:
        """name -> (median, max, n) for the classes of ticks."""
        classes = {
            "enabled, fault-free, default (no back-EMF comp.)": self.select(enabled=True, fault=False, bemf=False),
            "enabled, fault-free, back-EMF comp. on": self.select(enabled=True, fault=False, bemf=True),
            "  of which perturbation active": self.select(enabled=True, fault=False, pert=True),
            "with a latched fault": self.select(fault=True),
            "drive disabled": self.select(enabled=False, fault=False),
            "all ticks": self.select(),
        }
        return {k: (statistics.median(v), max(v), len(v)) for k, v in classes.items() if v}


BUDGET = 200
# The budget holds for every tick of the shipped default configuration: drive
# enabled, no fault, back-EMF compensation off (perturbation on or off).
BUDGET_CASE = {"enabled": True, "fault": False, "bemf": False}
# With back-EMF compensation on (the velocity observer runs): every such tick.
BUDGET_BEMF = 240
BUDGET_BEMF_CASE = {"enabled": True, "fault": False, "bemf": True}


def _bench_trace(elf: Path | None):
    """Run the bench image traced: (image, symbols, executed pcs, per-tick tags, main's range)."""
    elf = build_image("bench") if elf is None else elf
    syms = symbols(elf)
    pcs, tmp = trace_pcs(elf)
    try:
        tags = np.fromfile(tmp / "bench.bin", dtype="<u4").tolist()
    finally:
        shutil.rmtree(tmp, ignore_errors=True)
    return elf, syms, pcs, tags, syms["main"]


def tick_stats(elf: Path | None = None) -> TickStats:
    elf, syms, pcs, tags, main = _bench_trace(elf)
    calib = {
        "known_seq17": count_calls(pcs, syms["known_seq17"], main),
        "known_loop": count_calls(pcs, syms["known_loop"], main),
    }
    expected = {"known_seq17": [17], "known_loop": [3 * 5 + 2, 3 * 100 + 2]}
    ticks = count_calls(pcs, syms["mc_cell_tick"], main)
    if len(ticks) != len(tags):
        raise ToolError(f"counted {len(ticks)} ticks but the target logged {len(tags)}")
    # the decoder ISR is called from the static helper move_to (inlined into main or not)
    qcaller = syms.get("move_to", main)
    return TickStats(
        calib,
        expected,
        ticks,
        tags,
        count_calls(pcs, syms["mc_quad_update"], qcaller),
        count_calls(pcs, syms["mc_quad_snapshot"], main),
    )


def tick_profile(elf: Path | None = None) -> tuple[int, list[tuple[str, int]], list[str]]:
    """Where the instructions of one enabled, fault-free tick with a perturbation go:
    (total, [(function, instructions)], executed disassembly lines)."""
    elf, syms, pcs, tags, main = _bench_trace(elf)
    # enabled, perturbation active, back-EMF compensation off (the default), no fault
    want = next(i for i, t in enumerate(tags) if (t & 0x7) == 0x5 and not t >> 16)
    entry = syms["mc_cell_tick"][0]
    starts = [s for s in np.nonzero(pcs == entry)[0] if s and main[0] <= pcs[s - 1] < sum(main)]
    s = starts[want]
    k = s
    while not (main[0] <= pcs[k] < sum(main)):
        k += 1
    seg = [int(p) for p in pcs[s:k]]
    spans = sorted((a, a + n, name) for name, (a, n) in syms.items() if n)
    dis = _run(["arm-none-eabi-objdump", "-d", "--no-show-raw-insn", str(elf)])
    text = {}
    for ln in dis.splitlines():
        m = re.match(r"^\s+([0-9a-f]+):\s+(.*)$", ln)
        if m:
            text[int(m.group(1), 16)] = m.group(2).strip()

    def owner(pc):
        for lo, hi, name in spans:
            if lo <= pc < hi:
                return name
        return "?"

    per: dict[str, int] = {}
    lines = []
    last = None
    for pc in seg:
        f = owner(pc)
        per[f] = per.get(f, 0) + 1
        if f != last:
            lines.append(f"--- {f}")
            last = f
        lines.append(f"  {pc:6x}: {text.get(pc, '?')}")
    return len(seg), sorted(per.items(), key=lambda kv: -kv[1]), lines
