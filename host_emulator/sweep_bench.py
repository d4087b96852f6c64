"""Benchmark of the Dask sweep: points per second at 1 and 2 workers, per-task overhead, a 1,000-point sweep.

    python -m host_emulator.sweep_bench --points 200 --workers 1 2 --big 1000 --plot docs/img/sweep_bench.png

* run time of one point: evaluate_points([spec]) in this process (the 16-cell hil default, t_end_s simulated
  seconds, observables and dispersion included), median of --repeat;
* per-task overhead: median round trip of an empty task on a warm 1-worker local cluster (submit -> result);
* points/s at W workers: a sweep of --points points on a warm local cluster of W single-threaded worker
  processes (cluster start not counted), chunked as the sweep command chunks them;
* the --big-point sweep: the full `sweep` call (cluster start, dataset, no plots) at the largest W, wall time.
Timing on a shared machine is noisy: compare the ratios measured side by side.
"""

from __future__ import annotations

import argparse
import logging
import math
import os
import statistics
import tempfile
import time
from collections.abc import Sequence
from pathlib import Path
from typing import Any


def _specs(points, t_end):
    from .sweep import point_specs

    n = max(1, points)
    return point_specs(
        "default", {"params.sigma": [0.05 + 0.04 * i / max(1, n - 1) for i in range(n)]}, None, [f"t_end_s={t_end!r}"]
    )[0]


def _noop():
    return None


def measure(
    points: int = 200, workers: Sequence[int] = (1, 2), t_end: float = 10.0, repeat: int = 5, big: int = 1000
) -> dict:
    from distributed import Client, LocalCluster, as_completed

    from .sweep import evaluate_points, sweep

    specs = _specs(points, t_end)
    evaluate_points(specs[:1])  # compile / import outside the timing
    one = []
    for k in range(repeat):
        t0 = time.perf_counter()
        evaluate_points([specs[k % len(specs)]])
        one.append(time.perf_counter() - t0)
    res: dict[str, Any] = {"point_s": statistics.median(one), "t_end_s": t_end, "cores": os.cpu_count(), "rates": {}}
    for w in workers:
        with (
            LocalCluster(
                n_workers=w,
                threads_per_worker=1,
                processes=True,
                dashboard_address=None,
                scheduler_kwargs={"dashboard": False},
                silence_logs=logging.ERROR,
            ) as cl,
            Client(cl) as c,
        ):
            c.run(lambda: evaluate_points(_specs(1, 0.1)))  # warm every worker
            if w == min(workers):
                rt = []
                for _ in range(max(20, repeat)):
                    t0 = time.perf_counter()
                    c.submit(_noop, pure=False).result()
                    rt.append(time.perf_counter() - t0)
                res["task_overhead_s"] = statistics.median(rt)
            size = max(1, min(32, math.ceil(len(specs) / (4 * w))))
            t0 = time.perf_counter()
            futs = [c.submit(evaluate_points, specs[i : i + size], pure=False) for i in range(0, len(specs), size)]
            for f in as_completed(futs):
                f.result()
            res["rates"][w] = len(specs) / (time.perf_counter() - t0)
    if big:
        n = int(round(math.sqrt(big)))
        grid = {
            "params.sigma": list(map(float, __import__("numpy").linspace(0.04, 0.12, big // 10))),
            "perturbation.1.torque_Nm": [0.005 + 0.004 * i for i in range(10)],
        }
        del n
        with tempfile.TemporaryDirectory() as d:
            t0 = time.perf_counter()
            sweep(
                "default", grid, out=d, fixed=[f"t_end_s={t_end!r}"], workers=max(workers), progress=False, plots=False
            )
            res["big_points"], res["big_wall_s"] = big // 10 * 10, time.perf_counter() - t0
    return res


def plot(res: dict, path: str | Path) -> None:
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 3.4), constrained_layout=True)
    a, b = fig.subplots(1, 2)
    ws = sorted(res["rates"])
    a.bar([str(w) for w in ws], [res["rates"][w] for w in ws], color="C0")
    a.set_xlabel("workers")
    a.set_ylabel("points / s")
    a.set_title(f"sweep throughput ({res['t_end_s']:g} s per point, {res['cores']} cores)", fontsize=9)
    b.bar(
        ["run of one point", "Dask task round trip"],
        [1e3 * res["point_s"], 1e3 * res["task_overhead_s"]],
        color=["C1", "C2"],
    )
    b.set_ylabel("ms")
    b.set_title("per-task overhead against a 16-cell hil point", fontsize=9)
    fig.savefig(path, dpi=110)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator.sweep_bench",
        description=__doc__.split("\n\n")[0],
        epilog="example: python -m host_emulator.sweep_bench --points 200 --big 1000 --plot docs/img/sweep_bench.png",
    )
    ap.add_argument("--points", type=int, default=200, help="points per throughput measurement (default 200)")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2], help="worker counts to compare (default 1 2)")
    ap.add_argument("--t-end", type=float, default=10.0, help="simulated seconds per point (default 10)")
    ap.add_argument("--repeat", type=int, default=5, help="repeats of the single-point timing (default 5)")
    ap.add_argument("--big", type=int, default=1000, help="points of the full sweep timed end to end (0: skip)")
    ap.add_argument("--plot", default=None, metavar="PNG", help="write the figure here")
    a = ap.parse_args(argv)
    if a.points < 1 or min(a.workers) < 1 or not a.t_end > 0 or a.big < 0:
        ap.error("--points, --workers, --t-end must be positive and --big >= 0")
    r = measure(a.points, a.workers, a.t_end, a.repeat, a.big)
    print(
        f"one point (16-cell hil, {a.t_end:g} s): {1e3 * r['point_s']:.1f} ms; Dask task round trip: "
        f"{1e3 * r['task_overhead_s']:.1f} ms ({100 * r['task_overhead_s'] / r['point_s']:.0f} % of a point)"
    )
    base = r["rates"][min(r["rates"])]
    for w, v in sorted(r["rates"].items()):
        print(f"  {w} worker(s): {v:.1f} points/s ({v / base:.2f}x)")
    if a.big:
        print(
            f"  {r['big_points']}-point sweep at {max(a.workers)} workers (cluster start, dataset included): "
            f"{r['big_wall_s']:.1f} s"
        )
    if a.plot:
        plot(r, a.plot)
        print(f"  wrote {a.plot}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
