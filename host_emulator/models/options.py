"""Model switches of a scene ([model_options]) and perturbations, validated with errors that name the key."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, fields
from typing import Any

from .steppers import DEFAULT_STEPPER, STEPPERS

CHAINS = ("alpha", "beta")


class ConfigError(ValueError):
    """A scene or option value is invalid; the message names the key."""


@dataclass(frozen=True)
class NoiseOptions:
    """Seeded noise. Spreads are relative standard deviations of a per-cell/per-bond factor
    1 + s*N(0,1) (clipped at 0.2); encoder noise is hil only."""

    seed: int = 0
    band_spread: float = 0.0  # stiffness factor of each band pair (bond), both chains
    eta_spread: float = 0.0  # honey viscosity factor of each cell (alpha chain)
    encoder_jitter_counts: float = 0.0  # std dev of the sampled encoder position, counts
    encoder_glitch_prob: float = 0.0  # per encoder per plant step: an illegal AB pair


@dataclass(frozen=True)
class ModelOptions:
    """[model_options] of a scene. Defaults: the physics the source's own simulations use."""

    inertia: bool = True
    bands: str = "cubic"  # "cubic" (docs/physics.md#band-torque fit, slack, x band_scale) | "linear" (table k)
    beta_geometry: str = "small"  # "small" | "geometric" (docs/physics.md#band-torque full form)
    stepper: str = DEFAULT_STEPPER
    dt: float | None = None  # largest plant step, s (None: a quarter of the stable limit; adaptive steppers: no cap)
    tol: float | None = None  # adaptive steppers (dop853, lattice): error tolerance per step (None: DEFAULT_TOL)
    dt_out: float = 0.01  # output sample interval, s
    perturb_via: str = "plant"  # hil: "plant" (external torque, like a hand) | "firmware" (mc_cell_perturb)
    substeps: int | None = None  # hil: plant steps per control tick (None: from dt / stable limit)
    points_per_cell: int = 4  # continuum grid
    noise: NoiseOptions = field(default_factory=NoiseOptions)


DEFAULT_TOL = 1e-6  # tol when an adaptive stepper runs without one (about 5e-9 rad on the 16-cell lattice scene)
TOL_RANGE = (1e-13, 1e-1)  # tighter than 1e-13 is below double rounding for these states; looser is not a tolerance

_CHOICES = {
    "bands": ("cubic", "linear"),
    "beta_geometry": ("small", "geometric"),
    "perturb_via": ("plant", "firmware"),
}


def _num(key, v, *, integer=False, positive=False, nonneg=False):
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise ConfigError(f"{key} = {v!r}: expected a number")
    if integer and (not float(v).is_integer()):
        raise ConfigError(f"{key} = {v!r}: expected an integer")
    if not math.isfinite(v):
        raise ConfigError(f"{key} = {v!r}: must be finite")
    if positive and not v > 0:
        raise ConfigError(f"{key} = {v!r}: must be > 0")
    if nonneg and v < 0:
        raise ConfigError(f"{key} = {v!r}: must be >= 0")
    return int(v) if integer else float(v)


def parse_noise(d: dict, prefix: str = "model_options.noise") -> NoiseOptions:
    if not isinstance(d, dict):
        raise ConfigError(f"{prefix}: expected a table")
    known = {f.name for f in fields(NoiseOptions)}
    for k in d:
        if k not in known:
            raise ConfigError(f"unknown key {prefix}.{k}; known: {', '.join(sorted(known))}")
    kw = {}
    for k, v in d.items():
        if k == "seed":
            kw[k] = _num(f"{prefix}.seed", v, integer=True, nonneg=True)
        elif k == "encoder_glitch_prob":
            kw[k] = _num(f"{prefix}.{k}", v, nonneg=True)
            if kw[k] > 1:
                raise ConfigError(f"{prefix}.{k} = {v!r}: a probability must be <= 1")
        else:
            kw[k] = _num(f"{prefix}.{k}", v, nonneg=True)
    return NoiseOptions(**kw)


def parse_options(d: dict, prefix: str = "model_options") -> ModelOptions:
    if not isinstance(d, dict):
        raise ConfigError(f"{prefix}: expected a table")
    known = {f.name for f in fields(ModelOptions)}
    kw: dict[str, Any] = {}
    for k, v in d.items():
        key = f"{prefix}.{k}"
        if k not in known:
            raise ConfigError(f"unknown key {key}; known: {', '.join(sorted(known))}")
        if k == "noise":
            kw[k] = parse_noise(v, key)
        elif k == "inertia":
            if not isinstance(v, bool):
                raise ConfigError(f"{key} = {v!r}: expected true or false")
            kw[k] = v
        elif k in _CHOICES:
            if v not in _CHOICES[k]:
                raise ConfigError(f"{key} = {v!r}: expected one of {', '.join(_CHOICES[k])}")
            kw[k] = v
        elif k == "stepper":
            if v not in STEPPERS:
                raise ConfigError(f"{key} = {v!r}: expected one of {', '.join(sorted(STEPPERS))}")
            kw[k] = v
        elif k in ("dt", "dt_out"):
            kw[k] = _num(key, v, positive=True)
        elif k == "tol":
            kw[k] = _num(key, v, positive=True)
            if not TOL_RANGE[0] <= kw[k] <= TOL_RANGE[1]:
                raise ConfigError(f"{key} = {v!r}: expected {TOL_RANGE[0]:g} <= tol <= {TOL_RANGE[1]:g}")
        elif k in ("substeps", "points_per_cell"):
            kw[k] = _num(key, v, integer=True, positive=True)
    return ModelOptions(**kw)


@dataclass(frozen=True)
class Perturbation:
    """External torque on one cylinder: cell is 1-based, torque in N*m, active start_s <= t < start_s + duration_s."""

    cell: int
    chain: str
    torque_Nm: float
    start_s: float
    duration_s: float

    def as_dict(self) -> dict:
        return {
            "cell": self.cell,
            "chain": self.chain,
            "torque_Nm": self.torque_Nm,
            "start_s": self.start_s,
            "duration_s": self.duration_s,
        }


_PERT_KEYS = ("cell", "chain", "torque_Nm", "start_s", "duration_s")


def parse_perturbation(d: dict, cells: int, where: str) -> Perturbation:
    if not isinstance(d, dict):
        raise ConfigError(f"{where}: expected a table")
    for k in d:
        if k not in _PERT_KEYS:
            raise ConfigError(f"unknown key {where}.{k}; known: {', '.join(_PERT_KEYS)}")
    missing = [k for k in _PERT_KEYS if k not in d]
    if missing:
        raise ConfigError(f"{where}: missing key(s) {', '.join(missing)}")
    cell = _num(f"{where}.cell", d["cell"], integer=True)
    if not 1 <= cell <= cells:
        raise ConfigError(f"{where}.cell = {cell}: must be in 1..{cells}")
    if d["chain"] not in CHAINS:
        raise ConfigError(f"{where}.chain = {d['chain']!r}: expected alpha or beta")
    return Perturbation(
        cell,
        d["chain"],
        _num(f"{where}.torque_Nm", d["torque_Nm"]),
        _num(f"{where}.start_s", d["start_s"], nonneg=True),
        _num(f"{where}.duration_s", d["duration_s"], nonneg=True),
    )
