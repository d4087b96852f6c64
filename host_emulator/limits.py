"""Checks of a run's values before any work: finite, in range, fit the firmware's integers, memory and step count within
the machine.

`check_run(scene)` returns the first problem as one line (the CLI prints it and exits 2) or None. It judges the
values as given; `check_solver(scene, solver)` judges the run's cost once every default, accuracy preset and
automatic step choice is resolved (the built solver's plant step), so `model_options.substeps`, a tiny inertia
that shrinks the automatic step, or a dt are all held to the same limit. controller.run_scene applies it to every
run (the CLI, the API, paper, robustness, serve) through construct.checked_solver; `batch_budget` bounds runs x cost
for sweeps and repeats. The checks build nothing: checked_solver and scene_cost (construct.py) build the solver and
apply them, and are importable from here under their old names.
"""

from __future__ import annotations

import math
import os
from typing import TYPE_CHECKING

from metacell_common.outpaths import check_out_dir as _check_out_dir

from .models.options import ConfigError

if TYPE_CHECKING:
    from .scene import Scene

INT32 = 2**31
MAX_CELL_STEPS = 1e10  # plant steps x cells: about an hour at the compiled loop's speed
FIRMWARE_PARAMS = ("k_ab", "k1", "k2", "sigma", "alpha_star")  # sent as int32 micro-units (uN*m/rad, urad)
RANGES = {  # physically meaningful ranges; outside them the solvers slow to a halt
    "band_scale": (1e-3, 100.0),
    "eta_scale": (1e-3, 1e3),
    "gamma": (1e-4, 1e3),
}
JITTER_MAX_COUNTS = 400.0  # one revolution of the encoder
POINTS_MAX = 256
MAX_BATCH_CELL_STEPS = 24 * MAX_CELL_STEPS  # a sweep, paper or robustness batch: about a day of one core
REALTIME_CELL_STEPS_PER_S = MAX_CELL_STEPS / 3600  # what one core is held to: serve must keep real time


def cell_weight(scene: Scene) -> float:
    """What one cell step of the scene's lattice costs in cell steps of the open chain (the unit of the limits):
    1 on the open chain (its own compiled kernels); any other lattice goes through the plant's edge list, measured
    (2026-11-26, lattice, symplectic Euler, 4096 cells) at 2.1x the chain's per cell on a square sheet (2 bonds per
    cell) and 2.9x on a hexagonal one (3): 0.5 + 0.8 x bonds per cell."""
    t = scene.topology
    return 1.0 if t.is_open_chain else 0.5 + 0.8 * t.nbond / t.n


# the image tier's cost is the boards', not the plant's: about 1.6 s of one core per board second on the default
# scene (docs/image-tier.md), so half an hour of board time is about the hour the other limits allow
IMAGE_MAX_T_END_S = 1800.0
# The image tier's cost in seconds of CPU, judged before a board boots (image_cost): the boards' own work, the
# rounds in which the world meets them, and the encoder edges of edge storms, over the bring-up and the run.
# Measured with the default scene's images (2026-11-26, 16 cells): the boards 1.53-1.70 s of CPU per board second
# for all 17 (docs/image-tier.md, Figures); a round 0.85 us on one thread and about 12 us per thread on more (the
# pool's wake-up: 15 us on two, 44 on four, 195 on sixteen); an encoder edge about 6 us (full-speed edges,
# docs/image-tier.md).
IMAGE_CPU_PER_BOARD_S = 0.1  # s of CPU per board per board second
IMAGE_BRING_UP_S = 2.5  # board time before scene time 0: the crystal's 2 s, USB, the cells configured (~2.43 s)
IMAGE_WINDOW_S = 50e-6  # a round is at most the plant's window (image/model.py WINDOW_S)
IMAGE_ROUND_CPU_S = 0.85e-6  # s of CPU per round, one thread
IMAGE_ROUND_CPU_PER_THREAD_S = 12e-6  # ... and per thread on two or more
IMAGE_EDGE_CPU_S = 6e-6  # s of CPU per encoder edge (a glitch pair of an edge storm is two)
# the longest run the t_end limit allows at the default settings on two threads is about 3,600 s of CPU: room above it
IMAGE_MAX_CPU_S = 5400.0


class RunTooLarge(ConfigError):
    """A run (or a batch of runs) would not finish in reasonable time or memory; the message gives the figure."""


def mem_available() -> float:
    """Bytes the machine can give (MemAvailable), or 8 GiB where unknown."""
    try:
        with open("/proc/meminfo") as f:
            for line in f:
                if line.startswith("MemAvailable:"):
                    return float(line.split()[1]) * 1024
    except OSError:
        pass
    return 8.0 * 2**30


def check_run(scene: Scene) -> str | None:
    p, o = scene.params, scene.options
    for name in FIRMWARE_PARAMS:
        if getattr(p, name, None) is None:
            continue
        per = name in p.per_cell_keys
        for j, v in enumerate(p.per_cell(name)):
            if not (math.isfinite(v) and abs(float(v)) * 1e6 < INT32):  # a Python float: inf, no numpy overflow warning
                where = f"params.{name}[{j + 1}] (cell {j + 1})" if per else f"params.{name}"
                return f"{where} = {v}: does not fit the firmware's int32 micro-units (|value| < {INT32 / 1e6:g})"
    for name, (lo, hi) in RANGES.items():
        v = getattr(p, name, None)
        if v is not None and not (math.isfinite(v) and lo <= v <= hi):
            return f"params.{name} = {v}: expected {lo:g}..{hi:g}"
    jit = o.noise.encoder_jitter_counts
    if not (math.isfinite(jit) and 0 <= jit <= JITTER_MAX_COUNTS):
        return f"model_options.noise.encoder_jitter_counts = {jit}: expected 0..{JITTER_MAX_COUNTS:g} (one revolution)"
    t_end = scene.t_end_s
    if scene.model == "image" and t_end > IMAGE_MAX_T_END_S:
        return (
            f"t_end_s = {t_end} s: the image tier runs the flashed images instruction by instruction (about 1.6 s of "
            f"a core per board second); runs are limited to {IMAGE_MAX_T_END_S:g} s (about an hour)"
        )
    if scene.model == "image":
        from .image.model import encoder_noise_problem

        problem = encoder_noise_problem(o)
        if problem:
            return problem
        cost, why = image_cost(scene)
        if cost > IMAGE_MAX_CPU_S:
            return (
                f"the image tier would take about {cost:.3g} s of CPU ({why}; limit {IMAGE_MAX_CPU_S:g} s, about an "
                "hour and a half): a shorter run, model_options.image.round_s = 0 (rounds of the plant window), fewer "
                "threads or shorter edge storms"
            )
    if not o.dt_out <= t_end:
        return f"model_options.dt_out = {o.dt_out} s: must not exceed t_end_s = {t_end} s"
    if o.dt is not None and not o.dt <= o.dt_out:
        return f"model_options.dt = {o.dt} s: must not exceed dt_out = {o.dt_out} s"
    if o.dt is not None:
        steps = t_end / o.dt * scene.cells * cell_weight(scene)
        if steps > MAX_CELL_STEPS:
            return (
                f"model_options.dt = {o.dt} s over t_end_s = {t_end} s is {steps:.3g} cell steps "
                f"(limit {MAX_CELL_STEPS:.0e}, about an hour): use a larger dt or a shorter run"
            )
    n_out = t_end / o.dt_out + 1
    per_sample = scene.cells * 2 * 8 * 4  # alpha, beta float64, a few working copies
    if scene.model == "continuum":
        if o.points_per_cell > POINTS_MAX:
            return f"model_options.points_per_cell = {o.points_per_cell}: expected 1..{POINTS_MAX}"
        per_sample *= o.points_per_cell
    need = n_out * per_sample
    avail = mem_available()
    if need > 0.5 * avail:
        return (
            f"t_end_s = {t_end} s every dt_out = {o.dt_out} s needs about {need / 2**30:.3g} GiB of output "
            f"arrays; this machine has {avail / 2**30:.3g} GiB available"
        )
    return None


def image_cost(scene: Scene) -> tuple[float, str]:
    """Seconds of CPU an image-tier run takes, estimated before anything boots (the IMAGE_* figures above), and
    what makes them up (for the message)."""
    io = scene.options.image
    board_s = IMAGE_BRING_UP_S + scene.t_end_s
    boards = IMAGE_CPU_PER_BOARD_S * (scene.cells + 1) * board_s
    rnd = min(io.round_s, IMAGE_WINDOW_S) if io.round_s > 0 else IMAGE_WINDOW_S
    per_round = IMAGE_ROUND_CPU_S if io.threads == 1 else IMAGE_ROUND_CPU_PER_THREAD_S * io.threads
    rounds = board_s / rnd * per_round
    edges = 0.0
    for f in getattr(scene, "faults", ()):
        if f.kind == "edge_storm":
            edges += 2 * f.rate_hz * max(0.0, min(f.duration_s, scene.t_end_s - f.start_s)) * IMAGE_EDGE_CPU_S
    parts = [
        f"{boards:.3g} s for {scene.cells + 1} boards over {board_s:.4g} s of board time",
        f"{rounds:.3g} s for rounds of {rnd:.3g} s on {io.threads} thread{'s' if io.threads > 1 else ''}",
    ] + ([f"{edges:.3g} s for the edge storms' encoder edges"] if edges else [])
    return boards + rounds + edges, ", ".join(parts)


def check_out_dir(path: str | os.PathLike, opt: str = "--out") -> str | None:
    """Create the output directory now (before simulating); why not, or None (outpaths.check_out_dir)."""
    return _check_out_dir(path, opt)


def _step_cause(scene: Scene, solver) -> str:
    """Which key or automatic choice set the plant step (for the message)."""
    o, explicit = scene.options, set(getattr(scene, "explicit_options", ()))
    if scene.model == "hil" and "substeps" in explicit:
        return f"model_options.substeps = {o.substeps}"
    if "dt" in explicit:
        return f"model_options.dt = {o.dt} s"
    limit = getattr(solver, "limit", None)
    chain = getattr(solver, "limit_chain", "?")
    return (
        f"the automatic plant step (accuracy {getattr(scene, 'accuracy', 'balanced')}, stepper "
        f"{getattr(solver, 'stepper', '?')}: stable limit {limit:.3g} s on the {chain} chain, set by params.I_a/I_b, "
        "the band stiffness and the damping)"
        if limit
        else "the automatic plant step"
    )


def cell_steps(scene: Scene, solver) -> float:
    """Plant steps x cells of the whole run, in the open chain's cell steps (cell_weight; 0 for a solver without a
    fixed step)."""
    h = solver.plant_step_s()
    if h is None:
        return 0.0
    if not (h > 0 and math.isfinite(h)):
        return math.inf
    return scene.t_end_s / h * scene.cells * cell_weight(scene)


def check_solver(scene: Scene, solver) -> str | None:
    """The run's cost from its built solver (every preset and automatic choice resolved): one line, or None."""
    h = solver.plant_step_s()
    steps = cell_steps(scene, solver)
    if steps > MAX_CELL_STEPS:
        return (
            f"{_step_cause(scene, solver)}: plant step {h:.3g} s over t_end_s = {scene.t_end_s} s is {steps:.3g} cell "
            f"steps (limit {MAX_CELL_STEPS:.0e}, about an hour): use a larger step, fewer cells or a shorter run"
        )
    return None


def check_realtime(scene: Scene, solver, speed: float = 1.0) -> str | None:
    """serve paces the run to the wall clock: refuse a plant step no core could keep up with (the figure given)."""
    h = solver.plant_step_s()
    if h is None or not h > 0:
        return None
    per_s = scene.cells * cell_weight(scene) / h * speed
    if per_s > REALTIME_CELL_STEPS_PER_S:
        return (
            f"{_step_cause(scene, solver)}: plant step {h:.3g} s is {per_s:.3g} cell steps per wall second at speed "
            f"{speed:g} (limit {REALTIME_CELL_STEPS_PER_S:.3g}): serve could not keep real time"
        )
    return None


def batch_budget(total: float, what: str, limit: float = MAX_BATCH_CELL_STEPS) -> str | None:
    """The cell steps of a batch of runs (sweep, paper, robustness) against the limit: one line with the figure."""
    if total > limit:
        return (
            f"{what} is {total:.3g} cell steps in all (limit {limit:.3g}, about {limit / MAX_CELL_STEPS:g} hours of "
            "one core): fewer points, seeds or repeats, or shorter runs"
        )
    return None
