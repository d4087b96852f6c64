"""Batched ensembles for sweeps: many independent hil lattices advanced by one compiled call (he_hil_run_batch).

``run_batch(scenes)`` returns, for every scene, the same ``RunResult`` that ``controller.run_scene(scene)``
gives, bit for bit (t, alpha, beta), without Python per control tick or per output sample: Python only builds
each lattice (model, firmware cells, encoders) and then one C call runs them all to their end. Scenes the
batch cannot take (other models, firmware perturbation commands that Python schedules) run through
``run_scene`` in the same call, so any list of scenes works.

``keep="final"`` keeps only the last sample (t_end, final alpha and beta) for sweeps that need no
trajectory: 1,000 points x 1,001 samples x 32 angles would otherwise hold 256 MB.

Benchmark (the 1,000-point sweep of the 16-cell hil default, 10 s each):
    python -m host_emulator.batch --points 1000 --workers 1 2
"""

from __future__ import annotations

import argparse
import math
import os
import statistics
import time
from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from .controller import RunResult, run_scene
from .models.plant import NumericalInstability

if TYPE_CHECKING:
    from .scene import Scene

KEEP = ("trajectory", "final")


def _batchable(scene) -> bool:
    return scene.model == "hil" and not (scene.options.perturb_via == "firmware" and scene.perturbations)


def _build(scene):
    from .accuracy import resolve_options
    from .models import make_model

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
                    r = RunResult(r.t[-1:], r.alpha[-1:], r.beta[-1:], r.wall_s, r.info)
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
        results[idx[k]] = RunResult(t, a, b, wall / m, info)


# ---- benchmark: the 1,000-point sweep of the default scene ------------------------------------------------


def sweep_scenes(points: int, t_end_s: float = 10.0, base: str = "default") -> list[Scene]:
    """`points` variants of a scene: sigma, push cell and torque and the band-spread seed differ per point."""
    import tomllib

    from .scene import apply_overrides, resolve, scene_from_dict

    f = resolve(base)
    with open(f, "rb") as fh:
        d = tomllib.load(fh)
    out = []
    for i in range(points):
        sigma = 0.05 + 0.04 * ((i * 0.618033988749895) % 1.0)
        over = [
            f"t_end_s={t_end_s!r}",
            f"params.sigma={sigma!r}",
            f"perturbation.1.cell={1 + i % 16}",
            f"perturbation.1.torque_Nm={0.01 + 0.02 * ((i * 0.414213562) % 1.0)!r}",
            "model_options.noise.band_spread=0.02",
            f"model_options.noise.seed={i}",
        ]
        out.append(scene_from_dict(apply_overrides(d, over), str(f)))
    return out


def _worker(args):
    lo, hi, t_end_s, keep = args
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
    scenes = sweep_scenes(hi, t_end_s)[lo:hi]
    t0 = time.perf_counter()
    res = run_batch(scenes, keep=keep, errors="return")
    total = time.perf_counter() - t0
    batch = next((r.info["batch_wall_s"] for r in res if isinstance(r, RunResult)), 0.0)
    return total, batch, sum(isinstance(r, Exception) for r in res)


def bench_sweep(points: int, workers: int, t_end_s: float = 10.0, keep: str = "final") -> dict:
    """Wall time of a `points`-point sweep over `workers` processes (process start and set-up included)."""
    import multiprocessing as mp

    from .firmware import load

    load()  # compile outside the timing
    bounds = [(points * w // workers, points * (w + 1) // workers, t_end_s, keep) for w in range(workers)]
    t0 = time.perf_counter()
    if workers == 1:
        parts = [_worker(bounds[0])]
    else:
        with mp.get_context("fork").Pool(workers) as pool:
            parts = pool.map(_worker, bounds)
    wall = time.perf_counter() - t0
    compiled = sum(p[1] for p in parts)
    return {
        "points": points,
        "workers": workers,
        "wall_s": wall,
        "points_per_s": points / wall,
        "compiled_s": compiled,
        "overhead_per_point_ms": 1e3 * (sum(p[0] for p in parts) - compiled) / points,
        "failed": sum(p[2] for p in parts),
    }


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator.batch",
        description="Wall time of a sweep of the 16-cell hil default scene run as batches.",
    )
    ap.add_argument("--points", type=int, default=1000)
    ap.add_argument("--t-end", type=float, default=10.0, help="simulated seconds per point")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--repeat", type=int, default=1, help="timed sweeps per worker count (median reported)")
    ap.add_argument("--keep", choices=KEEP, default="final")
    ap.add_argument("--target-s", type=float, default=10.0)
    args = ap.parse_args(argv)
    if args.points < 1 or not (math.isfinite(args.t_end) and args.t_end > 0) or min(args.workers) < 1:
        ap.error("--points, --t-end and --workers must be positive")
    print(
        f"sweep: {args.points} points of the 16-cell hil default, {args.t_end:g} s each, keep={args.keep}, "
        f"{os.cpu_count()} cores"
    )
    for w in args.workers:
        runs = [bench_sweep(args.points, w, args.t_end, args.keep) for _ in range(max(1, args.repeat))]
        r = sorted(runs, key=lambda d: d["wall_s"])[len(runs) // 2]
        verdict = "meets" if r["wall_s"] <= args.target_s else "misses"
        print(
            f"  {w} worker(s): wall {r['wall_s']:.2f} s ({verdict} the {args.target_s:g} s target), "
            f"{r['points_per_s']:.0f} points/s, compiled loop {r['compiled_s']:.2f} s (summed over workers), "
            f"overhead {r['overhead_per_point_ms']:.2f} ms/point, failed {r['failed']}"
            + (
                f" [median of {len(runs)}: {statistics.median(d['wall_s'] for d in runs):.2f} s]"
                if len(runs) > 1
                else ""
            )
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
