"""Benchmark of batched sweeps: the wall time of an N-point sweep of the 16-cell hil default scene run through
host_emulator.workbench.batch.run_batch over 1 and 2 worker processes (`python -m host_emulator.benchmarks.batch
--points 1000 --workers 1 2`)."""

from __future__ import annotations

import argparse
import math
import os
import statistics
import time
from typing import TYPE_CHECKING

from ..controller import RunResult
from ..firmware import load
from ..scene import apply_overrides, resolve, scene_from_dict
from ..workbench.batch import KEEP, run_batch

if TYPE_CHECKING:
    from ..scene import Scene


def sweep_scenes(points: int, t_end_s: float = 10.0, base: str = "default") -> list[Scene]:
    """`points` variants of a scene: sigma, push cell and torque and the band-spread seed differ per point."""
    import tomllib

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
        prog="python -m host_emulator.benchmarks.batch",
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
