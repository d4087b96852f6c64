"""Models of the metamaterial (physics only) and their registry by name: continuum, lattice, hil."""

from __future__ import annotations

import importlib

from .options import ConfigError, ModelOptions, NoiseOptions, Perturbation
from .plant import NumericalInstability, draw_rig
from .solver import Solver
from .steppers import STEPPERS

# name -> the model class, or "module:Class" (relative to this package) imported on first use, so that the
# continuum model's scipy is imported only when it runs
_REGISTRY: dict[str, object] = {}


def register_model(name: str, target) -> None:
    """Register a model class (or a lazy "module:Class" path) under `name`; ValueError if the name is taken.

    The class takes (params, perturbations, options) and has .solver() returning a Solver."""
    if name in _REGISTRY:
        raise ValueError(f"model {name!r} registered twice")
    _REGISTRY[name] = target


def model_names() -> tuple[str, ...]:
    return tuple(_REGISTRY)


def model_class(name: str):
    """The class registered under `name` (imported now if it was registered lazily)."""
    try:
        target = _REGISTRY[name]
    except KeyError:
        raise ConfigError(f"model = {name!r}: expected one of {', '.join(_REGISTRY)}") from None
    if isinstance(target, str):
        mod, _, attr = target.partition(":")
        target = _REGISTRY[name] = getattr(importlib.import_module(mod, __name__), attr)
    return target


def make_model(name: str, params, perturbations=(), options: ModelOptions | None = None):
    """Instantiate a registered model by name, with the noise options' inertia and push draws applied
    (plant.draw_rig: nothing changes while those spreads are 0)."""
    cls = model_class(name)
    params, perturbations = draw_rig(params, list(perturbations), options)
    return cls(params, perturbations, options)


register_model("continuum", ".continuum_adapter:ContinuumModel")
register_model("lattice", ".lattice:LatticeModel")
register_model("hil", ".hil:HilModel")
register_model("image", "..image.model:ImageModel")

MODELS = model_names()

__all__ = [
    "MODELS",
    "make_model",
    "model_class",
    "model_names",
    "register_model",
    "Solver",
    "ModelOptions",
    "NoiseOptions",
    "Perturbation",
    "ConfigError",
    "NumericalInstability",
    "STEPPERS",
]
