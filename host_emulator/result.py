"""RunResult: the recorded trajectories of one run (t, alpha, beta), its wall time and the solver's info; what the
controller returns and batches, summaries and plots consume (he.run wraps it in workbench.api.RunResult)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np


@dataclass
class RunResult:
    t: np.ndarray
    alpha: np.ndarray  # (T, N) rad, cells in their numbering (a sheet's row by row: params.topology.grid makes it 2-D)
    beta: np.ndarray  # (T, N) rad
    wall_s: float
    info: dict = field(default_factory=dict)
    options: Any = None  # the ModelOptions the solver ran with (the accuracy preset applied), None if unknown

    @property
    def realtime_factor(self) -> float:
        return float(self.t[-1] / self.wall_s) if self.wall_s > 0 else float("inf")
