"""Models of the metamaterial (physics only) and their registry: continuum, lattice, hil."""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

from .options import ConfigError, ModelOptions, NoiseOptions, Perturbation
from .plant import NumericalInstability
from .steppers import STEPPERS

MODELS = ("continuum", "lattice", "hil")

if TYPE_CHECKING:
    from collections.abc import Sequence

    from ..params import Params
    from .continuum_adapter import ContinuumSolver
    from .hil import HilSolver
    from .lattice import LatticeSolver

    Solver = LatticeSolver | HilSolver | ContinuumSolver


def make_model(
    name: str, params: Params, perturbations: Sequence[Perturbation] = (), options: ModelOptions | None = None
) -> Any:  # the model class `name` asks for (LatticeModel, HilModel or ContinuumModel)
    """Instantiate a model by name (the continuum model is imported lazily: it needs scipy only)."""
    if name == "lattice":
        from .lattice import LatticeModel

        return LatticeModel(params, perturbations, options)
    if name == "hil":
        from .hil import HilModel

        return HilModel(params, perturbations, options)
    if name == "continuum":
        from .continuum_adapter import ContinuumModel

        return ContinuumModel(params, perturbations, options)
    raise ConfigError(f"model = {name!r}: expected one of {', '.join(MODELS)}")


__all__ = [
    "MODELS",
    "make_model",
    "ModelOptions",
    "NoiseOptions",
    "Perturbation",
    "ConfigError",
    "NumericalInstability",
    "STEPPERS",
]
