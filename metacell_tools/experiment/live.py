"""Live plot of a rig run: the emulator's PlotTracker fed from the frames the runner logs (primary clock)."""

from __future__ import annotations

import math

import numpy as np

from .runner import series, tail_arrays


class RigLive:
    """Feeds a host_emulator.workbench.trackers.PlotTracker with the samples of the current repeat.

    The runner calls `begin` when a repeat's drive is enabled and `poll` in its receive loop; `poll` does
    nothing until `interval_s` of primary clock has passed since the last feed, then hands the tracker every
    new row (time series as in the summary: t from the enable, missing samples held, absent cells 0)."""

    def __init__(self, tracker, n_cells: int, title: str = "", source: str = "rig", shape=None):
        self.tracker = tracker
        self.n = int(n_cells)
        self.shape = None if shape is None else tuple(shape)  # (rows, cols) on a sheet rig: the current field drawn
        self.title = title
        self.source = source  # "rig" or "rehearsal:<model>": what the title says the data is
        self.last_t = -math.inf
        self.rows_fed = 0

    @property
    def interval_s(self) -> float:
        return self.tracker.interval_s

    def begin(self, repeat: int, t_end_s: float) -> None:
        self.tracker.title = f"{self.title} ({self.source}), repeat {repeat}".strip()
        if self.shape is None:
            self.tracker.setup(self.n, t_end_s)
        else:
            self.tracker.setup(self.n, t_end_s, self.shape)
        self.last_t = -math.inf

    def poll(self, dec, t0: float | None, force: bool = False) -> int:
        """Feed the rows newer than the last fed one, at most once per interval (unless `force`); returns the
        rows fed."""
        if t0 is None or dec.t_raw is None:
            return 0
        now = dec.t_s - t0
        if not force and math.isfinite(self.last_t) and now < self.last_t + self.interval_s:
            return 0
        span = self.tracker.window_s if not math.isfinite(self.last_t) else now - self.last_t
        s = series(tail_arrays(dec, max(0.0, span) + 0.05), t0, 0.0)
        if s is None:
            return 0
        new = s.t > self.last_t
        if not new.any():
            return 0
        n = min(self.n, s.alpha.shape[1])
        a = np.zeros((int(new.sum()), self.n))
        b = np.zeros_like(a)
        a[:, :n], b[:, :n] = s.alpha[new, :n], s.beta[new, :n]
        self.tracker.sample_many(s.t[new], a, b)
        self.last_t = float(s.t[new][-1])
        self.rows_fed += len(a)
        return len(a)

    def finish(self, dec=None, t0: float | None = None) -> None:
        """Feed what is left of the repeat and redraw."""
        if dec is not None:
            self.poll(dec, t0, force=True)
        self.tracker.update()
