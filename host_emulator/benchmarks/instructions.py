"""Machine-independent cost of the hil loop: x86 instructions per cell and control tick, counted by callgrind.

    python -m host_emulator.benchmarks.instructions                  # the default scene, 2.5 s minus 0.5 s
    python -m host_emulator.benchmarks.instructions SCENE --set KEY=VALUE --t0 0.5 --t1 2.5 --json out.json

The same scene runs twice under ``valgrind --tool=callgrind``, to t0 and to t1 of simulated time, each in a fresh
Python process that first runs 0.1 s of it (so imports, lazy set-up and first-call paths are paid before either
measured run). The whole-process instruction counts differ by the cost of the (t1 - t0) rate cells ticks
between them: that marginal count divided by the cell-ticks is the figure, last line
``instructions per cell-tick: N``. It counts everything a run spends per tick: the compiled loop, the firmware,
the plant, and the Python that handles the output samples. Both processes run with PYTHONHASHSEED=0 and one
BLAS/OpenMP thread, so the counts repeat to a few hundred instructions (a spinning BLAS thread alone made them
wander by 20 million). Instruction counts do not depend on the machine's load or clock, only on the compiled
code: the compiler, its flags (metacell_common/firmware.py) and the x86-64 baseline instruction set (SSE2).

With callgrind_annotate on the PATH the marginal is also split by source: the firmware (lib/metacell), the
emulator's C (host_emulator/csrc) and everything else (Python, numpy, libc).
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shutil
import subprocess
import sys
import tempfile
from concurrent.futures import ThreadPoolExecutor
from dataclasses import asdict, dataclass, field
from pathlib import Path

from ..firmware import load
from ..models import ConfigError
from ..outpaths import check_out_file
from ..scene import load_scene

# Run in each measured process: 0.1 s of the scene (warm-up), then the scene to t_end. Nothing in it may depend on
# wall time, which under valgrind follows the machine's load: run_solver sizes its chunks of samples by wall time
# (CHUNK_WALL_S), so they are fixed at the largest, which a native run of the default scene reaches too; the
# firmware build is hashed once per process (firmware.RECHECK_S would re-hash it after a second of wall time, some
# million instructions under valgrind). Python's cyclic garbage collector is off for the measured run: when it
# runs depends on every allocation since start-up (the environment's size included), and one collection more in
# either run moved the figure by 1 per cell-tick.
_CHILD = """
import sys
import host_emulator.controller as controller
import metacell_common.firmware as firmware
from host_emulator.controller import build_solver, run_solver
controller.CHUNK_WALL_S = 1e9
firmware.RECHECK_S = 1e9
from host_emulator.scene import load_scene
sets = sys.argv[3:]
s = load_scene(sys.argv[1], sets + ["t_end_s=0.1"])
run_solver(build_solver(s), s.t_end_s)
import gc
gc.collect()
gc.disable()
s = load_scene(sys.argv[1], sets + ["t_end_s=" + sys.argv[2]])
run_solver(build_solver(s), s.t_end_s)
"""

ENV = {"PYTHONHASHSEED": "0", "OPENBLAS_NUM_THREADS": "1", "OMP_NUM_THREADS": "1", "MKL_NUM_THREADS": "1"}
# (group, markers in callgrind's "file:function" name); compiler intrinsics headers are inlined into our C only
GROUPS = (
    ("firmware (lib/metacell)", ("lib/metacell/",)),
    ("emulator C (host_emulator/csrc)", ("host_emulator/csrc/", "intrin.h:")),
)


class InstructionError(RuntimeError):
    """valgrind is missing or a measured run failed."""


@dataclass
class Count:
    """Instructions of one measured process, in total and by source group."""

    t_end_s: float
    total: int
    by_group: dict[str, int] = field(default_factory=dict)


@dataclass
class Marginal:
    scene: str
    cells: int
    rate_hz: float
    t0_s: float
    t1_s: float
    cell_ticks: int
    per_cell_tick: float
    by_group: dict[str, float]
    counts: list[Count]


def have_valgrind() -> bool:
    return shutil.which("valgrind") is not None


def _group_of(path: str) -> str:
    for name, markers in GROUPS:
        if any(m in path for m in markers):
            return name
    return "other (Python, numpy, libc)"


def _annotate(out: Path) -> dict[str, int]:
    """Self instructions by source group (callgrind_annotate's per-file:function table; inlined code counts in the
    file it comes from)."""
    if shutil.which("callgrind_annotate") is None:
        return {}
    text = subprocess.run(
        ["callgrind_annotate", "--auto=no", "--threshold=100", str(out)], capture_output=True, text=True, check=False
    ).stdout
    groups: dict[str, int] = {}
    for line in text.splitlines():
        m = re.match(r"\s*([\d,]+) \([^)]*\)\s+(.*?)(?:\s+\[.*\])?$", line)
        if m and "PROGRAM TOTALS" not in line:
            g = _group_of(m.group(2))
            groups[g] = groups.get(g, 0) + int(m.group(1).replace(",", ""))
    return groups


def count(scene: str, sets: list[str], t_end_s: float, workdir: Path) -> Count:
    """Instructions of one process that runs `scene` (with `sets`) to t_end_s under callgrind."""
    out = workdir / f"callgrind.{t_end_s:g}.out"
    cmd = [
        "valgrind",
        "--tool=callgrind",
        f"--callgrind-out-file={out}",
        sys.executable,
        "-c",
        _CHILD,
        scene,
        repr(float(t_end_s)),
        *sets,
    ]
    r = subprocess.run(cmd, capture_output=True, text=True, env={**os.environ, **ENV}, check=False)
    if r.returncode != 0 or not out.exists():
        tail = (r.stderr.strip().splitlines() or ["no output"])[-1]
        raise InstructionError(f"the measured run (t_end_s = {t_end_s:g}) failed under valgrind: {tail}")
    total = None
    for line in out.read_text(errors="replace").splitlines():
        if line.startswith(("summary:", "totals:")):
            total = int(line.split()[1])
    if total is None:
        raise InstructionError(f"no instruction total in {out}")
    return Count(t_end_s, total, _annotate(out))


def measure(scene: str = "default", sets: list[str] | None = None, t0: float = 0.5, t1: float = 2.5) -> Marginal:
    """The marginal instructions per cell and control tick of a hil scene between t0 and t1 of simulated time."""
    sets = list(sets or [])
    if not have_valgrind():
        raise InstructionError("valgrind is not installed (Debian: apt-get install valgrind)")
    if not 0 < t0 < t1:
        raise ValueError(f"--t0 {t0:g}, --t1 {t1:g}: need 0 < t0 < t1")
    sc = load_scene(scene, sets)
    if sc.model != "hil":
        raise ValueError(f"scene {sc.name!r} is a {sc.model} scene: instructions per cell-tick is a hil figure")
    load()  # compile outside the measured processes
    rate = float(sc.params.control_rate_hz)
    with tempfile.TemporaryDirectory(prefix="mc-callgrind-") as tmp:
        with ThreadPoolExecutor(2) as pool:
            counts = list(pool.map(lambda t: count(scene, sets, t, Path(tmp)), (t0, t1)))
    ticks = round((t1 - t0) * rate) * sc.cells
    groups = sorted(set(counts[0].by_group) | set(counts[1].by_group))
    by_group = {g: (counts[1].by_group.get(g, 0) - counts[0].by_group.get(g, 0)) / ticks for g in groups}
    return Marginal(
        sc.name, sc.cells, rate, t0, t1, ticks, (counts[1].total - counts[0].total) / ticks, by_group, counts
    )


def report(m: Marginal) -> str:
    lines = [
        f"scene {m.scene}: {m.cells} cells at {m.rate_hz:g} Hz, callgrind, whole process to {m.t1_s:g} s minus to "
        f"{m.t0_s:g} s of simulated time ({m.cell_ticks} cell-ticks)",
        f"  instructions: {m.counts[1].total:,} - {m.counts[0].total:,} = {m.counts[1].total - m.counts[0].total:,}",
    ]
    for g, v in sorted(m.by_group.items(), key=lambda kv: -kv[1]):
        lines.append(f"  {g:34s} {v:8.1f} per cell-tick")
    lines.append(f"instructions per cell-tick: {round(m.per_cell_tick)}")
    return "\n".join(lines)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator.benchmarks.instructions",
        description="x86 instructions per cell and control tick of a hil scene (callgrind; marginal between two "
        "run lengths, whole process). Exit 0 counted, 2 bad input, 3 valgrind missing or a run failed.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
        "  python -m host_emulator.benchmarks.instructions                 # the default scene, 2.5 s minus 0.5 s\n"
        "  python -m host_emulator.benchmarks.instructions --set params.bemf_comp=true\n"
        "  python -m host_emulator.benchmarks.instructions --t0 1 --t1 5 --json out/instructions.json",
    )
    ap.add_argument("scene", nargs="?", default="default", help="hil scene name or .toml path (default: default)")
    ap.add_argument("--set", action="append", default=[], metavar="KEY=VALUE", help="scene override (repeatable)")
    ap.add_argument("--t0", type=float, default=0.5, help="shorter run, s simulated (default 0.5)")
    ap.add_argument("--t1", type=float, default=2.5, help="longer run, s simulated (default 2.5)")
    ap.add_argument("--json", metavar="PATH", help="also write the counts as JSON")
    args = ap.parse_args(argv)
    problem = check_out_file(args.json, "--json") if args.json else None  # before minutes of callgrind
    if problem:
        print(f"error: {problem}", file=sys.stderr)
        return 2
    try:
        m = measure(args.scene, args.set, args.t0, args.t1)
    except (ValueError, ConfigError, FileNotFoundError) as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    except InstructionError as e:
        print(f"error: {e}", file=sys.stderr)
        return 3
    if args.json:
        Path(args.json).write_text(json.dumps(asdict(m), indent=1) + "\n")
    print(report(m))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
