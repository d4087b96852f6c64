"""Controller: runs a model's solver to t_end, feeding every output sample to the trackers (py-pde style).

Below it: the trackers it needs (tracking.py), the solver's construction behind limits' guards (construct.py) and
RunResult (result.py); nothing of the workbench (an import-linter contract in pyproject.toml holds it)."""

from __future__ import annotations

import time
from collections.abc import Sequence

import numpy as np

from .construct import build_solver, checked_solver
from .models import NumericalInstability, Solver
from .result import RunResult
from .tracking import ProgressTracker, RecordTracker, Tracker

# build_solver (the one construction path) and RunResult have their own modules; here under their old names
__all__ = ["RunResult", "build_solver", "run_scene", "run_solver"]


def run_solver(solver: Solver, t_end_s: float, trackers: Sequence[Tracker] = ()) -> RunResult:
    """Sample at t = 0, dt_out, ..., t_end (rounded to whole output intervals)."""
    if not (t_end_s > 0 and np.isfinite(t_end_s)):
        raise ValueError(f"t_end_s = {t_end_s!r}: must be a positive number")
    rec = RecordTracker()
    trackers = [rec, *trackers]
    t0 = time.perf_counter()
    if solver.whole_run:
        t, a, b = solver.run_all(t_end_s)
        if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
            raise NumericalInstability(f"{solver.model.name}: non-finite state in the output")
        for tr in trackers:
            tr.start(solver, t_end_s, len(t))
        for k in range(len(t)):
            for tr in trackers:
                tr.sample(t[k], a[k], b[k])
        for tr in trackers[1:]:
            tr.finish()
    else:
        n_out = max(1, round(t_end_s / solver.dt_out))
        for tr in trackers:
            tr.start(solver, n_out * solver.dt_out, n_out + 1)
        a, b = solver.state()
        for tr in trackers:
            tr.sample(0.0, a, b)
        try:
            _run_chunked(solver, n_out, trackers)  # Solver.advance_many: compiled chunks, or advance() calls
        finally:
            for tr in trackers[1:]:
                tr.finish()
    wall = time.perf_counter() - t0
    t, a, b = rec.result()
    return RunResult(t, a, b, wall, solver.info(), getattr(getattr(solver, "model", None), "options", None))


CHUNK_MAX_SAMPLES = 256  # output samples per compiled call at most
CHUNK_WALL_S = 0.2  # ... and about this much wall time, so progress bars and live trackers keep moving


def _run_chunked(solver, n_out: int, trackers: Sequence[Tracker]):
    """n_out samples through solver.advance_many (many samples per C call), fed to the trackers per chunk.

    The chunk starts at 8 samples and then holds ~CHUNK_WALL_S of wall time (at most CHUNK_MAX_SAMPLES).
    On an unstable run the samples completed before the failing one still reach the trackers."""
    left, chunk = n_out, 8
    while left > 0:
        w0 = time.perf_counter()
        try:
            t, a, b = solver.advance_many(min(chunk, left))
        except NumericalInstability as e:
            part = getattr(e, "samples", None)
            if part is not None and len(part[0]):
                for tr in trackers:
                    tr.sample_many(*part)
            raise
        for tr in trackers:
            tr.sample_many(t, a, b)
        left -= len(t)
        per = (time.perf_counter() - w0) / len(t)
        chunk = max(1, min(CHUNK_MAX_SAMPLES, int(CHUNK_WALL_S / per) if per > 0 else CHUNK_MAX_SAMPLES))


def run_scene(scene, *, progress: bool = True, trackers: Sequence[Tracker] = ()) -> RunResult:
    """Build the scene's model, run it and return the recorded trajectories.

    Refuses (limits.RunTooLarge, a ConfigError naming the key and the figure) a run whose resolved plant step
    makes it too long, before any step: every path to a run (the CLI, the API, paper, robustness) comes here."""
    solver = checked_solver(scene)
    extra = list(trackers)
    if progress:
        extra.append(ProgressTracker())
    res = run_solver(solver, scene.t_end_s, extra)
    faults = solver.faults()
    if faults is not None:
        res.info["cell_faults"] = faults
    return res
