"""Benchmark of the Dask sweep: points per second at 1 and 2 workers, per-task overhead, a 1,000-point sweep.

    python -m host_emulator.benchmarks.sweep --points 400 --workers 1 2 --repeat 3 --big 1000 \
        --json out/sweep_bench.json

Every figure is the median of --repeat measurements (the spread is printed beside it):

* one point: evaluate_points([spec]) in this process (the 16-cell hil default, --t-end simulated seconds,
  observables and dispersion included), i.e. what one Dask task does for a chunk of one point;
* per-task overhead: round trip of an empty task on a warm 1-worker local cluster (submit -> result), and its
  share of one point's run time;
* points/s at W workers: a sweep of --points points on a warm local cluster of W single-threaded worker
  processes (cluster start not counted), chunked as the `sweep` command chunks them;
* the machine's own scaling, for comparison: the same chunks through W forked processes without Dask. On a
  shared machine the cores another job holds are not ours; the Dask ratio is only as good as this one;
* the --big-point sweep: the full `sweep` call (cluster start, dataset, no plots) at the largest W, wall time.
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing as mp
import os
import statistics
import sys
import tempfile
import time
from typing import TypeVar

_T = TypeVar("_T")


def _specs(points: int, t_end: float) -> list[dict]:
    from ..workbench.sweep import point_specs

    n = max(1, points)
    return point_specs(
        "default", {"params.sigma": [0.05 + 0.04 * i / max(1, n - 1) for i in range(n)]}, None, [f"t_end_s={t_end!r}"]
    )[0]


def _noop() -> None:
    return None


def _chunks(specs: list[_T], workers: int) -> list[list[_T]]:
    from ..workbench.sweep import chunk_size

    size = chunk_size(len(specs), workers)  # as host_emulator.workbench.sweep chunks them
    return [specs[i : i + size] for i in range(0, len(specs), size)]


def _stats(values: list[float]) -> dict:
    return {"median": statistics.median(values), "min": min(values), "max": max(values), "runs": list(values)}


def measure(
    points: int = 400, workers=(1, 2), t_end: float = 10.0, repeat: int = 3, big: int = 1000, baseline: bool = True
) -> dict:
    """Every figure of the benchmark as a dict (seconds, points per second); see the module docstring."""
    from distributed import Client, as_completed

    from ..workbench.sweep import evaluate_points, local_cluster, sweep

    specs = _specs(points, t_end)
    evaluate_points(specs[:1])  # compile / import outside the timing
    one = []
    for k in range(max(5, repeat)):
        t0 = time.perf_counter()
        evaluate_points([specs[k % len(specs)]])
        one.append(time.perf_counter() - t0)
    res: dict = {
        "point_s": _stats(one),
        "t_end_s": t_end,
        "points": len(specs),
        "cores": os.cpu_count(),
        "load_avg_before": os.getloadavg()[0],
        "rates": {},
        "baseline_rates": {},
    }
    for w in workers:
        chunks = _chunks(specs, w)
        with local_cluster(w) as cl, Client(cl) as c:
            c.run(lambda: evaluate_points(_specs(1, 0.1)))  # warm every worker
            if w == min(workers):
                rt = []
                for _ in range(max(30, repeat)):
                    t0 = time.perf_counter()
                    c.submit(_noop, pure=False).result()
                    rt.append(time.perf_counter() - t0)
                res["task_overhead_s"] = _stats(rt)
            rates = []
            for _ in range(repeat):
                t0 = time.perf_counter()
                futs = [c.submit(evaluate_points, ch, pure=False) for ch in chunks]
                for f in as_completed(futs):
                    f.result()
                rates.append(len(specs) / (time.perf_counter() - t0))
            res["rates"][w] = _stats(rates)
        if baseline:
            rates = []
            with mp.get_context("fork").Pool(w) as pool:
                pool.map(evaluate_points, [specs[:1]] * w)  # warm
                for _ in range(repeat):
                    t0 = time.perf_counter()
                    pool.map(evaluate_points, chunks, chunksize=1)
                    rates.append(len(specs) / (time.perf_counter() - t0))
            res["baseline_rates"][w] = _stats(rates)
    if big:
        import numpy as np

        n_sigma = max(1, big // 10)
        grid = {
            "params.sigma": [float(v) for v in np.linspace(0.04, 0.12, n_sigma)],
            "perturbation.1.torque_Nm": [0.005 + 0.004 * i for i in range(10)],
        }
        walls = []
        for _ in range(repeat):
            with tempfile.TemporaryDirectory() as d:
                t0 = time.perf_counter()
                sweep(
                    "default",
                    grid,
                    out=d,
                    fixed=[f"t_end_s={t_end!r}"],
                    workers=max(workers),
                    progress=False,
                    plots=False,
                )
                walls.append(time.perf_counter() - t0)
        res["big_points"], res["big_wall_s"] = n_sigma * 10, _stats(walls)
    res["load_avg_after"] = os.getloadavg()[0]
    return res


def report(r: dict) -> str:
    """The figures as text (medians, with min-max of the repeats)."""

    def mm(s, scale=1.0, fmt=".1f"):
        return f"{scale * s['median']:{fmt}} (range {scale * s['min']:{fmt}}-{scale * s['max']:{fmt}})"

    p, o = r["point_s"], r["task_overhead_s"]
    lines = [
        f"one point (16-cell hil, {r['t_end_s']:g} s simulated): {mm(p, 1e3)} ms; "
        f"Dask task round trip: {mm(o, 1e3)} ms = {100 * o['median'] / p['median']:.0f} % of a point",
    ]
    k = len(_chunks(list(range(r["points"])), max(r["rates"]))[0])
    lines.append(
        f"  chunked as the sweep chunks them ({k} points per task at {max(r['rates'])} workers): "
        f"{1e3 * o['median'] / k:.2f} ms of overhead per point = {100 * o['median'] / k / p['median']:.1f} % of a point"
    )
    base = r["rates"][min(r["rates"])]["median"]
    mbase = r["baseline_rates"].get(min(r["rates"]), {}).get("median")
    for w in sorted(r["rates"]):
        v = r["rates"][w]
        line = f"  {w} worker(s), {r['points']} points: {mm(v)} points/s ({v['median'] / base:.2f}x)"
        if w in r["baseline_rates"]:
            b = r["baseline_rates"][w]
            line += f"; without Dask, {w} forked process(es): {mm(b)} points/s ({b['median'] / mbase:.2f}x)"
        lines.append(line)
    if "big_wall_s" in r:
        lines.append(
            f"  {r['big_points']}-point sweep at {max(r['rates'])} workers (cluster start, dataset included): "
            f"{mm(r['big_wall_s'])} s"
        )
    lines.append(
        f"  {r['cores']} cores; load average {r['load_avg_before']:.2f} before, {r['load_avg_after']:.2f} after "
        "(other jobs share the machine: compare figures measured side by side)"
    )
    return "\n".join(lines)


def plot(res: dict, path) -> None:
    import numpy as np
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8, 3.4), layout="constrained")
    a, b = fig.subplots(1, 2)
    ws = sorted(res["rates"])
    x = np.arange(len(ws))
    a.bar(x - 0.2, [res["rates"][w]["median"] for w in ws], 0.4, color="C0", label="Dask")
    if res["baseline_rates"]:
        a.bar(x + 0.2, [res["baseline_rates"][w]["median"] for w in ws], 0.4, color="0.6", label="forked, no Dask")
    a.set_xticks(x, [str(w) for w in ws])
    a.set_xlabel("workers")
    a.set_ylabel("points / s (median)")
    a.legend(fontsize=8, loc="lower center")
    a.set_title(f"sweep throughput ({res['t_end_s']:g} s per point, {res['cores']} shared cores)", fontsize=9)
    b.bar(
        ["run of one point", "Dask task round trip"],
        [1e3 * res["point_s"]["median"], 1e3 * res["task_overhead_s"]["median"]],
        color=["C1", "C2"],
    )
    b.set_ylabel("ms (median)")
    b.set_title("per-task overhead against a 16-cell hil point", fontsize=9)
    fig.savefig(path, dpi=110)


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator.benchmarks.sweep",
        description=__doc__.split("\n\n")[0],
        formatter_class=argparse.RawDescriptionHelpFormatter,
        epilog="examples:\n"
        "  python -m host_emulator.benchmarks.sweep                      # 400 points at 1 and 2 workers, 3 repeats, "
        "1,000-point sweep\n"
        "  python -m host_emulator.benchmarks.sweep --points 100 --big 0 --repeat 1   # a quick look\n"
        "  python -m host_emulator.benchmarks.sweep --json out/sweep_bench.json --plot out/sweep_bench.png",
    )
    ap.add_argument("--points", type=int, default=400, help="points per throughput measurement (default 400)")
    ap.add_argument("--workers", type=int, nargs="+", default=[1, 2], help="worker counts to compare (default 1 2)")
    ap.add_argument("--t-end", type=float, default=10.0, help="simulated seconds per point (default 10)")
    ap.add_argument(
        "--repeat", type=int, default=3, help="repeats of every measurement; medians are reported (default 3)"
    )
    ap.add_argument("--big", type=int, default=1000, help="points of the full sweep timed end to end (0: skip)")
    ap.add_argument("--no-baseline", action="store_true", help="skip the forked-process (no Dask) comparison")
    ap.add_argument("--json", default=None, metavar="FILE", help="write every measurement (all repeats) here")
    ap.add_argument("--plot", default=None, metavar="PNG", help="write the figure here")
    a = ap.parse_args(argv)
    if a.points < 1 or min(a.workers) < 1 or not (math.isfinite(a.t_end) and a.t_end > 0) or a.big < 0 or a.repeat < 1:
        ap.error("--points, --workers, --repeat, --t-end must be positive and --big >= 0")
    from ..outpaths import check_out_file, first_problem

    problem = first_problem(
        check_out_file(a.json, "--json") if a.json else None, check_out_file(a.plot, "--plot") if a.plot else None
    )
    if problem:
        print(f"benchmarks.sweep: error: {problem}", file=sys.stderr)
        return 2
    r = measure(a.points, a.workers, a.t_end, a.repeat, a.big, not a.no_baseline)
    print(report(r))
    if a.json:
        from ..provenance import provenance

        with open(a.json, "w") as f:
            json.dump(r | {"provenance": provenance()}, f, indent=1)
        print(f"  wrote {a.json}")
    if a.plot:
        plot(r, a.plot)
        print(f"  wrote {a.plot}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
