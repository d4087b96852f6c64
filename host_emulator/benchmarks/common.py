"""Shared helpers of the benchmarks: timing (best or median of k), work-precision interpolation, pinning, tables."""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import TypeVar

import numpy as np

T = TypeVar("T")


def pin_one_core() -> str:
    """Pin this process to one allowed CPU (figures comparable between machines with busy neighbours)."""
    if hasattr(os, "sched_setaffinity"):
        cpu = sorted(os.sched_getaffinity(0))[0]
        os.sched_setaffinity(0, {cpu})
        return f"cpu {cpu}"
    return "unpinned"


def clock() -> float:
    """The benchmarks' clock: CPU time of this (one-core-pinned) process. On an idle machine it equals wall
    time; on a shared one it leaves out the time other processes hold the core, which wall time does not."""
    return time.process_time()


def best_time(fn: Callable[[], T], repeat: int = 3, budget_s: float = 2.0) -> tuple[T, float]:
    """(result of the last call, smallest time in s on `clock`) over up to `repeat` calls (fewer when slow)."""
    t0 = clock()
    out = fn()
    best = spent = clock() - t0
    for _ in range(max(1, repeat) - 1):
        if spent > budget_s:
            break
        t0 = clock()
        out = fn()
        w = clock() - t0
        best = min(best, w)
        spent += w
    return out, best


def median_time(fn: Callable[[], T], repeat: int = 5, budget_s: float = 2.0) -> tuple[T, float]:
    """(result of the last call, median time in s on `clock`) over `repeat` calls after one untimed warm-up call
    (fewer timed calls once they have used `budget_s`, at least 3). Medians, not minima: on a shared machine the
    fastest of a few runs is luck as often as it is the code."""
    out = fn()
    times: list[float] = []
    while len(times) < max(1, repeat):
        t0 = clock()
        out = fn()
        times.append(clock() - t0)
        if len(times) >= 3 and sum(times) > budget_s:
            break
    return out, float(np.median(times))


@dataclass
class WPPoint:
    """One run of a work-precision sweep."""

    method: str  # e.g. "rk4" or "scipy DOP853"
    setting: str  # "dt=2.5e-4" or "rtol=1e-6"
    wall_s: float
    error: float  # max |angle - reference| over samples, cells and chains (rad); inf if it failed
    note: str = ""
    extra: dict = field(default_factory=dict)


def wall_at(points: list[WPPoint], target: float) -> float | None:
    """Wall time a method needs for max error `target`: log-log interpolation on its Pareto front
    (cheapest run reaching each error level). None when no run of the method reaches the target."""
    pts = sorted((p.wall_s, p.error) for p in points if math.isfinite(p.error) and p.error > 0)
    front: list[tuple[float, float]] = []  # increasing wall, strictly decreasing error
    for w, e in pts:
        if not front or e < front[-1][1]:
            front.append((w, e))
    if not front or front[-1][1] > target:
        return None
    if front[0][1] <= target:
        return front[0][0]
    for (w0, e0), (w1, e1) in zip(front[:-1], front[1:]):
        if e0 > target >= e1:
            if math.log(e1) == math.log(e0):  # errors an ulp apart: their logs round to the same value
                return w1
            f = (math.log(target) - math.log(e0)) / (math.log(e1) - math.log(e0))
            return math.exp(math.log(w0) + f * (math.log(w1) - math.log(w0)))
    return None  # pragma: no cover - covered by the checks above


def table(rows: list[list], header: list[str]) -> str:
    """Plain fixed-width table (what the docs paste)."""
    cells = [[str(c) for c in r] for r in [header] + rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(header))]
    lines = ["  ".join(c.ljust(w) for c, w in zip(r, widths)).rstrip() for r in cells]
    lines.insert(1, "  ".join("-" * w for w in widths))
    return "\n".join(lines)


def fmt(v: object, nd: int = 3) -> str:
    if v is None:
        return "-"
    if isinstance(v, float):
        if not math.isfinite(v):
            return "fail"
        return f"{v:.{nd}g}"
    return str(v)


def max_err(a: np.ndarray, b: np.ndarray) -> float:
    if a.shape != b.shape or not np.all(np.isfinite(a)):
        return math.inf
    return float(np.max(np.abs(a - b)))
