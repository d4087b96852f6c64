"""Speed benchmark: real-time factor of a scene (default: the 16-cell hil default) pinned to one core, and, for a hil
scene with valgrind installed, its machine-independent cost: x86 instructions per cell and control tick
(host_emulator.benchmarks.instructions)."""

from __future__ import annotations

import argparse
import os
import platform
import statistics
import time

from ..controller import build_solver, run_solver
from ..firmware import load
from ..provenance import machine_line
from ..scene import load_scene
from . import instructions as ins


def bench_main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator bench-speed",
        description="Print the real-time factor (simulated s per wall s) of a scene.",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
        "  python -m host_emulator bench-speed\n"
        "  python -m host_emulator bench-speed exp1_ccw_ccw --set t_end_s=5",
    )
    ap.add_argument("scene", nargs="?", default="default", help="scene name or .toml path (default: default)")
    ap.add_argument("--repeat", type=int, default=5, help="timed runs (the median is reported)")
    ap.add_argument(
        "--set", action="append", default=[], metavar="KEY=VALUE", help="scene override, as for run (repeatable)"
    )
    ap.add_argument("--cpu", type=int, default=None, help="pin to this CPU (default: the first allowed one)")
    ap.add_argument(
        "--no-instructions",
        action="store_true",
        help="skip the callgrind instruction count (hil scenes; about a minute, needs valgrind)",
    )
    args = ap.parse_args(argv)

    if hasattr(os, "sched_setaffinity"):
        cpus = sorted(os.sched_getaffinity(0))
        os.sched_setaffinity(0, {args.cpu if args.cpu is not None else cpus[0]})
    scene = load_scene(args.scene, args.set)
    load()  # compile outside the timing
    walls = []
    for _ in range(max(1, args.repeat)):
        solver = build_solver(scene)  # as `run` builds it: the scene's accuracy preset applies
        t0 = time.perf_counter()
        res = run_solver(solver, scene.t_end_s)
        walls.append(time.perf_counter() - t0)
    wall = statistics.median(walls)
    sim = float(res.t[-1])
    info = res.info
    print(
        f"scene {scene.name} ({scene.model}, {scene.cells} cells, {sim:g} s simulated) on one core "
        f"[python {platform.python_version()}]"
    )
    print(f"  machine: {machine_line()}")
    if scene.model == "hil":
        print(
            f"  control rate {info['control_rate_hz']} Hz, {info['substeps_per_tick']} plant step(s) per tick "
            f"({info['stepper']}), output every {info['dt_out_s']} s"
        )
        _print_instructions(args)
    print(
        f"  wall per run: median {wall * 1e3:.1f} ms (min {min(walls) * 1e3:.1f}, max {max(walls) * 1e3:.1f}, "
        f"{len(walls)} runs)"
    )
    if scene.model == "hil":
        ticks = round(sim * info["control_rate_hz"])
        print(
            f"  cost: {wall / (ticks * scene.cells) * 1e9:.1f} ns per cell and control tick "
            f"({ticks} ticks x {scene.cells} cells)"
        )
    print(f"  realtime factor: {sim / wall:.0f}x (requirement: >= 100x; target for the hil default: >= 1000x)")
    return 0 if sim / wall >= 100 or scene.name != "default" else 1


def _print_instructions(args: argparse.Namespace) -> None:
    """The callgrind count of the same scene (machine-independent), or one line saying why it is not there."""
    if args.no_instructions:
        return
    if not ins.have_valgrind():
        print("  instructions per cell-tick: not counted (valgrind is not installed)")
        return
    try:
        m = ins.measure(args.scene, args.set)
    except (ins.InstructionError, ValueError) as e:
        print(f"  instructions per cell-tick: not counted ({e})")
        return
    print(
        f"  instructions per cell-tick: {round(m.per_cell_tick)} (callgrind, whole process, {m.t1_s:g} s minus "
        f"{m.t0_s:g} s of simulated time: machine-independent; firmware {m.by_group.get(ins.GROUPS[0][0], 0):.0f}, "
        f"emulator C {m.by_group.get(ins.GROUPS[1][0], 0):.0f})"
    )
