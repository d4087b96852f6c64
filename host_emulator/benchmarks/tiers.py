"""`python -m host_emulator.benchmarks.tiers`: the tier and preset tables of docs/accuracy.md#tiers, as printed.

Per tier (host_emulator/tiers.py): what it models, its CPU time per simulated second on the default scene (3 s,
accuracy balanced, one pinned core, median of --repeat runs) and its max angle difference from the next tier up
on the same scene. Per preset (lattice and hil on the default scene): what it sets, its cost, and its integration
error: max |alpha - alpha of the same tier and components at a converged step| (lattice: dop853 at tol 1e-11;
hil: rk4 x 64 plant steps per tick). Then every shipped scene's cost at each preset, and where the presets' names
do not order their cost. Errors do not depend on the machine (tests/docs/test_tiers_table.py recomputes them);
times do, so the command prints its machine line first.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Sequence

import numpy as np

from ..accuracy import LEVELS, resolve_options
from ..construct import build_solver
from ..controller import run_solver
from ..provenance import machine_line
from ..scene import Scene, list_scenes, load_scene
from ..tiers import QUESTIONS, TIERS, UP, fmt_cost, pick
from .common import clock, pin_one_core

SECONDS = 3.0
SCENE_TABLE_MAX_CELLS = 256  # the scene table's sheets: the larger ones cost minutes per preset (docs/emulator.md)
TIER_ORDER = ("continuum", "lattice", "hil", "image")


def scene_for(tier: str, level: str = "balanced", name: str = "default", seconds: float = SECONDS) -> Scene:
    return load_scene(name, [f"model={tier}", f"t_end_s={seconds:g}", f"accuracy={level}"])


def alpha_of(scene: Scene, options=None) -> np.ndarray:
    s = build_solver(scene) if options is None else build_solver(scene, resolve=False, options=options)
    return run_solver(s, scene.t_end_s).alpha


def tier_error(tier: str, seconds: float = SECONDS, cache: dict | None = None) -> float:
    """max |alpha - alpha of the next tier up| (rad) on the default scene at balanced."""
    cache = {} if cache is None else cache
    for t in (tier, UP[tier]):
        if t not in cache:
            cache[t] = alpha_of(scene_for(t, seconds=seconds))
    a, b = cache[tier], cache[UP[tier]]
    n = min(len(a), len(b))
    return float(np.abs(a[:n] - b[:n]).max())


def resolved(scene: Scene):
    return resolve_options(
        scene.model, scene.params, scene.perturbations, scene.options, scene.accuracy, scene.explicit_options
    )


def converged(scene: Scene):
    """The scene's resolved options at a converged step (same tier, same components)."""
    o = resolved(scene)
    if scene.model == "lattice":
        return dataclasses.replace(o, stepper="dop853", tol=1e-11, dt=None)
    return dataclasses.replace(o, stepper="rk4", substeps=64, dt=None)


def preset_error(tier: str, level: str, seconds: float = SECONDS) -> float:
    """max |alpha - alpha at a converged step| (rad): the preset's integration error on the default scene."""
    sc = scene_for(tier, level, seconds=seconds)
    a, ref = alpha_of(sc), alpha_of(sc, converged(sc))
    return float(np.abs(a - ref).max())


def preset_sets(scene: Scene) -> str:
    """What the preset ran: stepper, step (or tolerance, or plant steps per tick) and beta geometry."""
    o = resolved(scene)
    if scene.model == "lattice":
        step = f"tol {o.tol:g}" if o.stepper == "dop853" else f"dt {o.dt:.3g} s"
    elif scene.model == "hil":
        step = f"{o.substeps} per tick"
    else:
        step = "per 50 us window"
    return f"{o.stepper}, {step}, {o.beta_geometry} beta"


def cost_ms(scene: Scene, repeat: int) -> float:
    """Median CPU ms per simulated second of run_solver (construction excluded)."""

    def go():
        s = build_solver(scene)
        t0 = clock()
        run_solver(s, scene.t_end_s)
        return clock() - t0

    times = [go() for _ in range(max(1, repeat) + 1)][1:]  # the first call warms caches and imports
    return float(np.median(times)) * 1e3 / scene.t_end_s


def scene_costs(name: str, repeat: int) -> list[str]:
    """A shipped scene's CPU ms per simulated second at fast, balanced, exact, and whether they come in that order
    (two levels that resolve to the same options are one run: the hil's fast and balanced)."""
    scenes = [load_scene(name, [f"t_end_s={SECONDS:g}", f"accuracy={lv}"]) for lv in LEVELS]
    c = [cost_ms(sc, repeat) for sc in scenes]
    same = resolved(scenes[0]) == resolved(scenes[1])
    if same:
        c[0] = c[1] = min(c[0], c[1])
    ok = c[0] <= c[1] <= c[2]
    return [fmt_cost(x) for x in c] + [("yes" if ok else "no") + (" (fast = balanced: one loop)" if same else "")]


def questions_table() -> str:
    """The questions a scene can state, the tiers that model each and the one model = "auto" picks."""
    rows = ["| question | asks | tiers that model it | auto picks |", "|---|---|---|---|"]
    for q, (what, tiers, _why) in QUESTIONS.items():
        rows.append(f"| `{q}` | {what} | {', '.join(tiers)} | {pick(q)[0]} |")
    return "\n".join(rows)


def fmt_err(x: float | None) -> str:
    return "-" if x is None else f"{x:.2g}"


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="python -m host_emulator.benchmarks.tiers", description=__doc__.splitlines()[0])
    ap.add_argument("--repeat", type=int, default=5, help="timed runs per figure (the median is printed)")
    ap.add_argument("--no-image", action="store_true", help="skip the image tier (about 5 s of CPU per run)")
    ap.add_argument("--no-scenes", action="store_true", help="skip the table of every shipped scene's presets")
    args = ap.parse_args(argv)
    if args.repeat < 1:
        print("error: --repeat must be >= 1", file=sys.stderr)
        return 2
    pin_one_core()
    print(f"# machine: {machine_line()}")
    print(f"# default scene, {SECONDS:g} s simulated; CPU time of one pinned core, median of {args.repeat} runs\n")
    print(questions_table() + "\n")
    tiers = [t for t in TIER_ORDER if not (args.no_image and t == "image")]
    cache: dict = {}
    print("| tier | models | CPU ms per simulated s (balanced) | max angle difference from the next tier up (rad) |")
    print("|---|---|---|---|")
    for t in tiers:
        reps = min(args.repeat, 2) if t in ("image", "continuum") else args.repeat
        cost = cost_ms(scene_for(t), reps)
        up = UP.get(t)
        err = f"{tier_error(t, cache=cache):.2g} (vs {up})" if up in tiers else "- (the top tier)"
        print(f"| {t} | {TIERS[t]} | {fmt_cost(cost)} | {err} |")
    print("\n| tier | level | runs | CPU ms per simulated s | integration error (rad) |")
    print("|---|---|---|---|---|")
    for t in ("lattice", "hil"):
        for lv in LEVELS:
            sc = scene_for(t, lv)
            print(
                f"| {t} | {lv} | {preset_sets(sc)} | {fmt_cost(cost_ms(sc, args.repeat))} | "
                f"{fmt_err(preset_error(t, lv))} |"
            )
    if not args.no_scenes:
        print("\n| scene | model | fast | balanced | exact | cost in the names' order |")
        print("|---|---|---|---|---|---|")
        for name, model, _ in list_scenes():
            if model not in ("lattice", "hil") or load_scene(name).cells > SCENE_TABLE_MAX_CELLS:
                continue  # the continuum ignores the knob; no shipped scene runs the image; large sheets: too dear
            print(f"| {name} | {model} | " + " | ".join(scene_costs(name, args.repeat)) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
