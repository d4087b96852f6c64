"""Batched ensembles for sweeps: many independent hil lattices advanced by one compiled call (he_hil_run_batch).

``run_batch(scenes)`` returns, for every scene, the same ``RunResult`` that ``controller.run_scene(scene)``
gives, bit for bit (t, alpha, beta), without Python per control tick or per output sample: Python only builds
each lattice (model, firmware cells, encoders) and then one C call runs them all to their end. Scenes the
batch cannot take (other models, firmware perturbation commands that Python schedules) run through
``run_scene`` in the same call, so any list of scenes works.

``keep="final"`` keeps only the last sample (t_end, final alpha and beta) for sweeps that need no
trajectory: 1,000 points x 1,001 samples x 32 angles would otherwise hold 256 MB.

Benchmark (the 1,000-point sweep of the 16-cell hil default, 10 s each):
    python -m host_emulator.benchmarks.batch --points 1000 --workers 1 2
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from ..accuracy import resolve_options
from ..controller import RunResult, run_scene
from ..models import make_model
from ..models.plant import NumericalInstability

if TYPE_CHECKING:
    from ..scene import Scene

KEEP = ("trajectory", "final")


def _batchable(scene) -> bool:
    return scene.model == "hil" and not (scene.options.perturb_via == "firmware" and scene.perturbations)


def _build(scene):
    options = resolve_options(
        scene.model,
        scene.params,
        scene.perturbations,
        scene.options,
        getattr(scene, "accuracy", "balanced"),
        getattr(scene, "explicit_options", ()),
    )
    model = make_model(scene.model, scene.params, scene.perturbations, options)
    solver = model.solver()
    n_out = max(1, round(scene.t_end_s / solver.dt_out))
    return solver, n_out


def run_batch(scenes: Sequence[Scene], *, keep: str = "trajectory", errors: str = "raise") -> list:
    """RunResult per scene, as run_scene(scene, progress=False) would return it (bit-identical t/alpha/beta).

    keep: "trajectory" (every output sample) or "final" (t = [t_end], alpha/beta of shape (1, n)).
    errors: "raise" (the first failing point's NumericalInstability, after all points ran) or "return"
    (that exception object in the failing point's place). info["batch_wall_s"] is the shared call's wall
    time; wall_s is that time divided by the number of points it ran.
    """
    if keep not in KEEP:
        raise ValueError(f"keep = {keep!r}: expected one of {', '.join(KEEP)}")
    if errors not in ("raise", "return"):
        raise ValueError(f"errors = {errors!r}: expected 'raise' or 'return'")
    scenes = list(scenes)
    results: list = [None] * len(scenes)
    idx = [i for i, s in enumerate(scenes) if _batchable(s)]
    for i, s in enumerate(scenes):
        if i not in set(idx):
            try:
                r = run_scene(s, progress=False)
                if keep == "final":
                    r = RunResult(r.t[-1:], r.alpha[-1:], r.beta[-1:], r.wall_s, r.info, r.options)
                results[i] = r
            except NumericalInstability as e:
                results[i] = e
    if idx:
        _run_hil_batch([scenes[i] for i in idx], keep, results, idx)
    if errors == "raise":
        for r in results:
            if isinstance(r, Exception):
                raise r
    return results


def _run_hil_batch(scenes, keep, results, idx):
    solvers, n_outs = zip(*(_build(s) for s in scenes))
    m = len(solvers)
    ffi, lib = solvers[0].model.ffi, solvers[0].model.lib
    outs = [np.empty((k, 2 * s.model.n)) if keep == "trajectory" else None for s, k in zip(solvers, n_outs)]
    keep_alive = []

    def ptrs(arrs):
        p = ffi.new("double *[]", m)
        for i, a in enumerate(arrs):
            if a is not None:
                b = ffi.from_buffer("double[]", a)
                keep_alive.append(b)
                p[i] = b
        return p

    hl = ffi.new("he_hil_t *[]", [s.h for s in solvers])
    rate = ffi.new("int64_t[]", [int(s.model.rate_hz) for s in solvers])
    tpo = ffi.new("int64_t[]", [int(s.ticks_per_out) for s in solvers])
    nsamp = ffi.new("int64_t[]", list(n_outs))
    xs, vs, op = ptrs([s.x for s in solvers]), ptrs([s.v for s in solvers]), ptrs(outs)
    done = ffi.new("int64_t[]", m)
    rc = ffi.new("int32_t[]", m)
    x0 = [s.x.copy() for s in solvers]
    w0 = time.perf_counter()
    lib.he_hil_run_batch(m, hl, rate, tpo, nsamp, xs, vs, op, done, rc)
    wall = time.perf_counter() - w0
    for k, (s, n_out) in enumerate(zip(solvers, n_outs)):
        n, k_done = s.model.n, int(done[k])
        s.tick = k_done * s.ticks_per_out
        s.t = s.tick / s.model.rate_hz
        if rc[k] != lib.HE_OK:
            s._pt[0] = s.t
            results[idx[k]] = s._error(int(rc[k]))
            continue
        info = s.info()
        info["batch_wall_s"] = wall
        info["cell_faults"] = s.faults()
        traj = outs[k]  # an array exactly when keep == "trajectory"
        if traj is not None:
            t = np.concatenate(
                [
                    [0.0],
                    np.arange(s.ticks_per_out, (n_out + 1) * s.ticks_per_out, s.ticks_per_out)[:n_out]
                    / s.model.rate_hz,
                ]
            )
            a = np.concatenate([x0[k][None, :n], traj[:, :n]])
            b = np.concatenate([x0[k][None, n:], traj[:, n:]])
        else:
            t = np.array([s.t])
            a, b = s.x[None, :n].copy(), s.x[None, n:].copy()
        results[idx[k]] = RunResult(t, a, b, wall / m, info, s.model.options)
