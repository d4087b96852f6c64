"""Runs of a sheet design: its scenes (a candidate's laws, its pushes, a draw of the rig's uncertainty) as one
batched hil ensemble (workbench.batch), each run judged by sheet_landing; the search (step 2) and the
verification (step 3) over them."""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

from ...analysis.observables import is_steady
from ...models.options import ModelOptions, NoiseOptions, Perturbation
from ...params import Params
from ...physics import reaction
from ..batch import run_batch
from .constants import (
    CHECK_SEED0,
    CLOSE_WEIGHT,
    FULL_BONUS,
    NOISE,
    NOMINAL_PUSH,
    PUSH_DURATIONS_S,
    PUSH_TORQUES_NM,
    SEARCH_PUSHES,
    SEARCH_SEED0,
    VERIFY_SEED0,
)
from .search import evolve_around
from .sheet_landing import region_measures, sheet_closeness, sheet_miss_reason
from .sheet_linear import sheet_linear_score
from .sheet_target import SheetPush, SheetTarget
from .space import Space, _shape_ok


def noise_options(seed: int | None) -> NoiseOptions:
    """The draw `seed` of the rig's uncertainty (NOISE); None: no noise."""
    kw: dict[str, Any] = dict(NOISE)
    return NoiseOptions() if seed is None else NoiseOptions(seed=seed, **kw)


def sheet_scene(base, p: Params, pushes: Sequence[SheetPush], torque: float, duration: float, seed: int | None):
    """The base Scene (a sheet's) with the laws p, these pushes (torque N m for duration s from 0.1 s) and, with a
    seed, that draw of the rig's uncertainty (NOISE); seed None: no noise."""
    top = p.topology
    perts = tuple(
        Perturbation(top.cell_of(q.row, q.col), "alpha", q.sign * torque, 0.1, duration, q.row, q.col) for q in pushes
    )
    noise = noise_options(seed)
    opts = dataclasses.replace(base.options, noise=noise)
    return dataclasses.replace(base, cells=p.cells, params=p, perturbations=perts, options=opts)


def judge(target: SheetTarget, p: Params, scenes: list) -> list[dict]:
    """Run the scenes as one batched ensemble; per run {landed, why, steady, torque_fraction, final_alpha_rad,
    pattern_kind, dominant_wavelength_cells} or {landed: False, error}."""
    out: list[dict] = []
    cap = p.kt * p.vmax_v
    for r in run_batch(scenes, errors="return"):
        if isinstance(r, BaseException):
            out.append({"landed": False, "why": "error", "error": f"{type(r).__name__}: {r}"})
            continue
        a, b = r.alpha[-1], r.beta[-1]
        ra, rb = reaction(p, a, b)
        tf = float(max(np.abs(ra).max(), np.abs(rb).max()) / cap)
        steady = is_steady(r.t, r.alpha, r.beta)
        why = sheet_miss_reason(target, a, steady, tf <= 1.0)
        m = region_measures(target, a)
        out.append(
            {
                "landed": why is None,
                "why": why,
                "steady": bool(steady),
                "torque_fraction": tf,
                "pattern_kind": m["pattern_kind"],
                "dominant_wavelength_cells": m["dominant_wavelength_cells"],
                "orientation_deg": m["orientation_deg"],
                "final_alpha_rad": [round(float(v), 4) for v in a],
            }
        )
    return out


def sheet_search(
    space: Space,
    target: SheetTarget,
    pushes: Sequence[SheetPush],
    base,
    x0: np.ndarray,
    *,
    seeds: int = 4,
    maxiter: int = 4,
    popsize: int = 6,
    seed: int = 1,
    report: Callable[[str], None] = lambda s: None,
) -> tuple[np.ndarray, float, list[dict], int]:
    """Step 2 as on a chain: the first guess over `seeds` draws (SEARCH_SEED0..) and the push range's corners; a
    candidate off the linear theory's constraints (sheet_linear_score < 1) is not run and scores below any that is; one
    landing in all its runs is run again on as many fresh draws (CHECK_SEED0..) and, landing there too,
    ends the search; else differential evolution (vectorized: one batched ensemble per generation) around it.
    Returns (x, score, history, runs)."""
    history: list[dict] = []
    runs = [0]
    done = [False]

    def one(x) -> float:
        p = space.params(x)
        if not _shape_ok(p):
            return -1.0
        lin = sheet_linear_score(p, target)[0]
        if lin < 1:  # off the linear theory's constraints (e.g. a rest law that rests only thanks to the motors)
            history.append({"fraction": 0.0, "misses": ["linear theory"]})
            return lin - 2.0  # below every candidate that runs (those score >= 0)
        sc = [sheet_scene(base, p, pushes, *NOMINAL_PUSH, SEARCH_SEED0 + s) for s in range(seeds)]
        sc += [sheet_scene(base, p, pushes, tq, du, None) for tq, du in SEARCH_PUSHES]
        res = judge(target, p, sc)
        runs[0] += len(sc)
        hits = [r["landed"] for r in res]
        part = [
            1.0
            if r["landed"]
            else CLOSE_WEIGHT * sheet_closeness(target, np.asarray(r["final_alpha_rad"]))
            if "final_alpha_rad" in r
            else 0.0
            for r in res
        ]
        if all(hits):
            more = judge(
                target, p, [sheet_scene(base, p, pushes, *NOMINAL_PUSH, CHECK_SEED0 + s) for s in range(len(sc))]
            )
            runs[0] += len(sc)
            part += [1.0 if r["landed"] else 0.0 for r in more]
            hits += [r["landed"] for r in more]
            if all(hits):
                done[0] = True
                part.append(1.0 + FULL_BONUS * len(part))
        history.append({"fraction": float(np.mean(hits)), "misses": sorted({str(r["why"]) for r in res if r["why"]})})
        return float(np.mean(part))

    s0 = one(x0)
    report(f"hil search, first guess: lands in {history[-1]['fraction']:.3f} of its runs")
    if done[0] or maxiter == 0:
        return x0, s0, history, runs[0]
    gen = [0]

    def generation(best: float) -> None:
        gen[0] += 1
        report(f"hil search, generation {gen[0]}: best so far {best:.3f}")

    x, s = evolve_around(
        space,
        x0,
        s0,
        lambda xs: np.array([one(x) for x in xs]),
        lambda: done[0],
        spread=0.1,
        popsize=popsize,
        seed=seed,
        maxiter=maxiter,
        generation=generation,
    )
    return x, s, history, runs[0]


def sheet_verify(
    scene,
    target: SheetTarget,
    seeds: int = 20,
    *,
    pushes_too: bool = True,
    model: str | None = None,
    seed0: int = VERIFY_SEED0,
) -> dict:
    """Run a sheet scene (as `run` loads it) over `seeds` draws of the rig's uncertainty (seed0..) and, with
    pushes_too, the documented push range without noise; model: the same draws in another model (the lattice,
    its own accuracy preset). The fraction of each that lands, and every run's verdict."""
    base = scene
    if model is not None:
        free = ("stepper", "substeps", "dt", "perturb_via")  # the hil's own knobs: the model's preset sets them
        d = ModelOptions()
        opts = dataclasses.replace(base.options, **{k: getattr(d, k) for k in free})
        keep = tuple(k for k in base.explicit_options if k not in free)
        base = dataclasses.replace(base, model=model, options=opts, explicit_options=keep)
    p = base.params
    sc = []
    for s in range(seeds):
        sc.append(dataclasses.replace(base, options=dataclasses.replace(base.options, noise=noise_options(seed0 + s))))
    grid = [(tq, du) for tq in PUSH_TORQUES_NM for du in PUSH_DURATIONS_S] if pushes_too else []
    for tq, du in grid:
        perts = tuple(
            dataclasses.replace(q, torque_Nm=math.copysign(tq, q.torque_Nm), duration_s=du) for q in base.perturbations
        )
        sc.append(
            dataclasses.replace(
                base, perturbations=perts, options=dataclasses.replace(base.options, noise=NoiseOptions())
            )
        )
    res = judge(target, p, sc)
    for i, r in enumerate(res):
        r.update(
            {"seed": seed0 + i} if i < seeds else {"torque_Nm": grid[i - seeds][0], "duration_s": grid[i - seeds][1]}
        )
    fs = float(np.mean([r["landed"] for r in res[:seeds]])) if seeds else None
    fp = float(np.mean([r["landed"] for r in res[seeds:]])) if grid else None
    return {
        "model": base.model,
        "seeds": seeds,
        "seed0": seed0,
        "noise": NOISE,
        "fraction_seeds": fs,
        "push_torques_Nm": list(PUSH_TORQUES_NM) if grid else [],
        "push_durations_s": list(PUSH_DURATIONS_S) if grid else [],
        "fraction_pushes": fp,
        "max_torque_fraction": max((r.get("torque_fraction", 0.0) for r in res), default=0.0),
        "runs": res,
    }
