"""Continuum model adapter: wraps simulate_continuum (models/continuum.py) behind the controller's solver interface."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

import numpy as np

from .options import ModelOptions, Perturbation
from .plant import NumericalInstability
from .solver import Solver

if TYPE_CHECKING:
    from ..params import Params


def _spread(m: ContinuumModel):
    """The noise model's band and viscosity factors (plant.spreads), or None when it draws none."""
    nz = m.options.noise
    if not (nz.band_spread > 0 or nz.eta_spread > 0):
        return None
    from .plant import spreads

    return spreads(m.params, m.options, m.n)


class ContinuumModel:
    name = "continuum"

    def __init__(
        self, params: Params, perturbations: Sequence[Perturbation] = (), options: ModelOptions | None = None
    ) -> None:
        self.params = params
        self.n = params.cells
        self.options = options or ModelOptions()
        self.perturbations = list(perturbations)

    def solver(self) -> ContinuumSolver:
        return ContinuumSolver(self)


class ContinuumSolver(Solver):
    """Batch solver: the whole run happens in one call (simulate_continuum: scipy BDF on a chain, ETDRK4 on a sheet)."""

    model: ContinuumModel

    whole_run = True

    def __init__(self, model: ContinuumModel):
        self.model = model
        self.dt_out = model.options.dt_out

    def info(self) -> dict:
        sheet = self.model.params.topology.is_sheet
        return {
            "stepper": "ETDRK4, adaptive, on the grid's FFT/DCT (continuum sheet)"
            if sheet
            else "scipy BDF (continuum)",
            "dt_out_s": self.dt_out,
            "points_per_cell": self.model.options.points_per_cell,
        }

    def run_all(self, t_end_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        try:
            from .continuum import simulate_continuum
        except ImportError as e:  # pragma: no cover - only while the module is missing
            raise RuntimeError(f"continuum model unavailable: {e}") from e
        m = self.model
        try:
            t, a, b = simulate_continuum(
                m.params,
                m.n,
                t_end_s,
                [q.as_dict() for q in m.perturbations],
                dt_out_s=self.dt_out,
                points_per_cell=m.options.points_per_cell,
                spread=_spread(m),
            )
        except (ArithmeticError, FloatingPointError) as e:
            raise NumericalInstability(f"continuum: {e}") from e
        except RuntimeError as e:
            if type(e).__name__ == "ContinuumError":
                raise NumericalInstability(f"continuum: {e}") from e
            raise
        return np.asarray(t), np.asarray(a), np.asarray(b)
