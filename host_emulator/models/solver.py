"""The solver interface the controller drives (py-pde style): one base class instead of duck-typed hasattr checks."""

from __future__ import annotations

from typing import Protocol

import numpy as np


class Model(Protocol):
    """What the controller, the trackers and the benchmarks read of any solver's model (each solver class narrows
    ``model`` to its own model class)."""

    name: str
    n: int  # cells


class Solver:
    """Advances a model's state and reports it at output samples t = k * dt_out.

    A stepping solver overrides ``advance`` (one output interval) and may override ``advance_many`` (many
    intervals per compiled call, bit-identical to as many ``advance`` calls). A solver that can only run the
    whole span in one call (the continuum's scipy BDF) sets ``whole_run = True`` and overrides ``run_all``.

    Per control tick access to the hil loop (the bus rig) is HilSolver.run_ticks, a public method, not the
    solver's private members.
    """

    whole_run = False
    model: Model  # set by every solver's __init__
    dt_out: float = 0.0
    t: float = 0.0

    def info(self) -> dict:
        return {"dt_out_s": self.dt_out}

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        raise NotImplementedError

    def advance(self) -> None:
        """One output interval."""
        raise NotImplementedError(f"{type(self).__name__} runs whole spans only (run_all)")

    def advance_many(self, k_max: int):
        """Up to k_max output intervals; (t (k,), alpha (k, n), beta (k, n)). Default: k_max advance() calls."""
        k_max = int(k_max)
        if k_max < 1:
            raise ValueError(f"k_max = {k_max}: must be >= 1")
        ts, al, be = [], [], []
        for _ in range(k_max):
            self.advance()
            a, b = self.state()
            ts.append(self.t)
            al.append(a)
            be.append(b)
        return np.array(ts), np.array(al), np.array(be)

    def run_all(self, t_end_s: float):
        """(t, alpha, beta) of the whole run, for whole_run solvers."""
        raise NotImplementedError(f"{type(self).__name__} steps (advance / advance_many), it has no run_all")

    def plant_step_s(self) -> float | None:
        """The plant step the solver will take, s, after every preset and automatic choice (an adaptive lattice:
        the largest step it can hold; None: a solver whose step nothing bounds, the continuum's BDF).
        limits.check_solver turns it into the run's cost."""
        return None

    def faults(self) -> list[int] | None:
        """Per-cell firmware fault bits, or None for a model without firmware."""
        return None
