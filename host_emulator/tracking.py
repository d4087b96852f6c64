"""The trackers the controller itself needs, below it (py-pde's trackers/): the base class, recording every sample
and a tqdm progress bar. Live printing and plotting are the workbench's (host_emulator/workbench/trackers.py)."""

from __future__ import annotations

import sys
from typing import TYPE_CHECKING, TextIO

import numpy as np

if TYPE_CHECKING:
    from .models import Solver

__all__ = ["Tracker", "RecordTracker", "ProgressTracker"]


class Tracker:
    """Base: start(solver, t_end), sample(t, alpha, beta) or sample_many(t[k], alpha[k, n], beta[k, n]), finish().

    The controller calls sample_many with a chunk of consecutive samples when the solver runs many samples per
    compiled call; the default passes them one by one to sample(), so a tracker need only define sample()."""

    def start(self, solver: Solver, t_end_s: float, n_samples: int) -> None:
        pass

    def sample(self, t: float, alpha: np.ndarray, beta: np.ndarray) -> None:
        pass

    def sample_many(self, t: np.ndarray, alpha: np.ndarray, beta: np.ndarray) -> None:
        for k in range(len(t)):
            self.sample(t[k], alpha[k], beta[k])

    def finish(self) -> None:
        pass


class RecordTracker(Tracker):
    """Stores every sample in preallocated arrays (t, alpha (T, N), beta (T, N))."""

    def start(self, solver: Solver, t_end_s: float, n_samples: int) -> None:
        n = solver.model.n
        self.t = np.empty(n_samples)
        self.alpha = np.empty((n_samples, n))
        self.beta = np.empty((n_samples, n))
        self.i = 0

    def sample(self, t: float, alpha: np.ndarray, beta: np.ndarray) -> None:
        self.t[self.i] = t
        self.alpha[self.i] = alpha
        self.beta[self.i] = beta
        self.i += 1

    def sample_many(self, t: np.ndarray, alpha: np.ndarray, beta: np.ndarray) -> None:
        k = len(t)
        self.t[self.i : self.i + k] = t
        self.alpha[self.i : self.i + k] = alpha
        self.beta[self.i : self.i + k] = beta
        self.i += k

    def result(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return self.t[: self.i], self.alpha[: self.i], self.beta[: self.i]


class ProgressTracker(Tracker):
    """A tqdm bar in simulated seconds, shown only once the run has taken over `delay_s` of wall time."""

    def __init__(self, delay_s: float = 1.0, file: TextIO | None = None, disable: bool | None = None) -> None:
        """disable None (default): shown on a terminal only (tqdm's rule); True: never."""
        self.delay_s = delay_s
        self.file = file or sys.stderr
        self.disable = disable

    def start(self, solver: Solver, t_end_s: float, n_samples: int) -> None:
        from tqdm import tqdm  # a start-up cost only when a bar is made

        self.bar = tqdm(
            total=round(t_end_s, 6),
            unit="sim s",
            delay=self.delay_s,
            file=self.file,
            disable=self.disable,
            leave=False,
            bar_format="{l_bar}{bar}| {n:.2f}/{total:.2f} sim s [{elapsed}<{remaining}]",
        )
        self.last = 0.0

    def sample(self, t: float, alpha: np.ndarray, beta: np.ndarray) -> None:
        if t > self.last:
            self.bar.update(t - self.last)
            self.last = t

    def sample_many(self, t: np.ndarray, alpha: np.ndarray, beta: np.ndarray) -> None:
        if len(t):
            self.sample(float(t[-1]), alpha[-1], beta[-1])

    def finish(self) -> None:
        self.bar.close()
