"""Benchmark: real-time factor of the image tier (16 cell images and the primary's on Unicorn, the plant) on the
default scene and with every encoder at the motors' full speed, on one thread and on two.

python -m host_emulator.benchmarks.image [--seconds 2] [--reps 3] [--threads 1 2] [--scenario default full-speed]

Each measurement brings a fresh world up (boot, USB, the cells configured: not timed), then times `seconds` of
board time: the wall time (real-time factor = board seconds / wall seconds) and the process CPU time (every
thread's), medians over `reps`. Machine-independent figures come first: the CPU cycles the boards executed per
board second (fast-forwarded idle passes excluded; the same on every machine) and how often the emulator
started and stopped the CPUs, and how often the fast-forward compared a pass with the one before, and how often it
probed a pass of the primary's that read the time. "full-speed": the plant at rest, all 32 encoders turning back
and forth at the motors' no-load speed at full supply (fwcheck's cpu-budget figure), so every cell takes its worst
edge rate. "default-untimed": the default scene with `fast_forward_timed` off (the primary's polling loops run in
full).
"""

from __future__ import annotations

import argparse
import statistics
import sys
import time
from dataclasses import dataclass

from metacell_common.target.board import NO_LOAD_RAD_PER_V_S, SUPPLY_V
from protocol.codec import COUNTS_PER_RAD

from ..construct import build_solver
from ..image import ImageTierUnavailable
from ..image.build import build_images
from ..image.laptop import Laptop
from ..image.model import ImageSolver, bring_up
from ..image.world import World, WorldConfig
from ..models.options import ConfigError
from ..params import Params
from ..progress import bar
from ..provenance import machine_line
from ..scene import load_scene


@dataclass
class Measurement:
    wall_s: float
    cpu_s: float
    executed_cycles: dict[str, int]  # per board, executed (not fast-forwarded) over the timed interval
    runs: int  # emulation starts, all boards
    ff_checks: dict[str, int]  # per board, loop() entries the fast-forward compared with the one before
    ff_probes: int  # the primary's probes of passes that read the time (fast_forward_timed)
    edges: int  # encoder edges the cells' pins saw (counts)


def full_speed_counts_s() -> float:
    """Encoder counts per second at the motors' no-load speed at full supply (the CPU budget's figure)."""
    return NO_LOAD_RAD_PER_V_S * SUPPLY_V * COUNTS_PER_RAD


def full_speed_world(seconds: float, threads: int) -> tuple[World, Laptop]:
    """The "full-speed" scenario brought up: 16 cells and the primary, the plant at rest, every encoder turning
    back and forth at full speed for `seconds` (and 10 ms more) from 1 ms after bring-up. (world, laptop)."""
    p = Params(cells=16)
    w = World(p, build_images(16), config=WorldConfig(threads=threads))
    lap, _ = bring_up(w, p)
    rate = full_speed_counts_s()
    t0 = w.t + 0.001
    for cell in range(1, 17):
        for chain in ("alpha", "beta"):  # back and forth inside the firmware's runaway limit (800 counts)
            w.spin(cell, chain, rate, t0, t0 + seconds + 0.01, back_and_forth=600)
    return w, lap


def _snapshot(world) -> tuple[dict[str, int], int, dict[str, int], int]:
    out, runs, checks, probes = {}, 0, {}, 0
    for b in world.boards:
        i = world.info(b.index)
        out[b.name] = int(i.cycles) - int(i.ff_cycles_skipped)
        runs += int(i.runs)
        checks[b.name] = int(i.ff_checks)
        if b.name == "primary":
            probes = int(i.ff_probes)
    return out, runs, checks, probes


def measure(scenario: str, seconds: float, threads: int) -> Measurement:
    """One measurement: a fresh world brought up (not timed), then `seconds` of board time timed."""
    edges = 0
    if scenario in ("default", "default-untimed"):
        opts = ["model=image", f"t_end_s={seconds + 1}", f"model_options.image.threads={threads}"]
        if scenario == "default-untimed":
            opts.append("model_options.image.fast_forward_timed=false")
        scene = load_scene("default", opts)
        solver = build_solver(scene)
        assert isinstance(solver, ImageSolver)
        w = solver.world
    else:
        w, lap = full_speed_world(seconds, threads)
        edges = round(32 * full_speed_counts_s() * seconds)
    c0, r0, k0, p0 = _snapshot(w)
    t_wall, t_cpu = time.perf_counter(), time.process_time()
    if scenario != "full-speed":
        t_end = solver.t + seconds
        while solver.t < t_end - 1e-9:
            solver.advance()
    else:
        lap.pump(seconds)
    wall, cpu = time.perf_counter() - t_wall, time.process_time() - t_cpu
    c1, r1, k1, p1 = _snapshot(w)
    return Measurement(
        wall, cpu, {k: c1[k] - c0[k] for k in c1}, r1 - r0, {k: k1[k] - k0[k] for k in k1}, p1 - p0, edges
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator.benchmarks.image",
        description=__doc__.split("\n\n")[0],
        epilog="example: python -m host_emulator.benchmarks.image --seconds 1 --reps 1",
    )
    ap.add_argument("--seconds", type=float, default=2.0, help="board seconds timed per measurement (default 2)")
    ap.add_argument("--reps", type=int, default=3, help="measurements per case; medians are quoted (default 3)")
    ap.add_argument("--threads", type=int, nargs="+", default=[1, 2], help="thread counts (default 1 2)")
    ap.add_argument(
        "--scenario",
        nargs="+",
        default=["default", "full-speed"],
        choices=("default", "full-speed", "default-untimed"),
        help="cases (default: default full-speed; default-untimed: the default scene, fast_forward_timed off)",
    )
    args = ap.parse_args(argv)
    if not 0.1 <= args.seconds <= 60 or not 1 <= args.reps <= 20 or not all(1 <= t <= 16 for t in args.threads):
        print("benchmark: --seconds 0.1..60, --reps 1..20, --threads 1..16", file=sys.stderr)
        return 2

    print(f"machine: {machine_line()}")
    print(f"image tier, {args.seconds:g} board seconds per measurement, median of {args.reps}")
    pb = bar(len(args.scenario) * len(args.threads) * args.reps, desc="image benchmark", unit="run")
    for scenario in args.scenario:
        for threads in args.threads:
            ms = []
            try:
                for _ in range(args.reps):
                    ms.append(measure(scenario, args.seconds, threads))
                    pb.update()
            except (ImageTierUnavailable, ConfigError) as e:
                pb.close()
                print(f"benchmark: {e}", file=sys.stderr)
                return 3
            m = ms[-1]
            cells = sum(v for k, v in m.executed_cycles.items() if k.startswith("cell")) / 16 / args.seconds
            prim = m.executed_cycles.get("primary", 0) / args.seconds
            cell_checks = sum(v for k, v in m.ff_checks.items() if k.startswith("cell")) / 16 / args.seconds
            prim_checks = m.ff_checks.get("primary", 0) / args.seconds
            wall = statistics.median(x.wall_s for x in ms)
            cpu = statistics.median(x.cpu_s for x in ms)
            print(f"{scenario}, {threads} thread{'s' if threads > 1 else ''}:")
            print(
                f"  executed per board second: {cells / 1e6:.2f} M cycles per cell, {prim / 1e6:.2f} M the primary "
                f"(of 48 M); {m.runs / args.seconds:,.0f} emulation starts"
                + (f"; {m.edges / args.seconds:,.0f} encoder edges" if m.edges else "")
            )
            print(
                f"  idle-pass compares per board second (fast-forward): {cell_checks:,.0f} per cell, "
                f"{prim_checks:,.0f} the primary; {m.ff_probes / args.seconds:,.0f} probes of the primary's "
                "timed passes"
            )
            print(
                f"  real-time factor {args.seconds / wall:.2f}x (wall {wall / args.seconds:.2f} s per board second, "
                f"CPU {cpu / args.seconds:.2f} s; runs {', '.join(f'{x.wall_s:.2f}' for x in ms)} s)"
            )
    pb.close()
    return 0


if __name__ == "__main__":
    sys.exit(main())
