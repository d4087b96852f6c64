"""The accuracy knob (`accuracy = "fast" | "balanced" | "exact"` in a scene, `run --accuracy`): stepper, step and model
fidelity.

Presets (chosen from the measured work-precision and fidelity tables, docs/accuracy.md). A model option the
scene sets explicitly (model_options.stepper, .dt, .substeps, .beta_geometry) always wins over the preset.

lattice (ideal reaction; a fixed step as a fraction of the computed stable limit of the preset's stepper, or an
adaptive stepper's error tolerance):
    fast      rk4, dt = 0.8 x limit      ~1e-3 rad max angle error over 3 s of exp. 3 (16 cells)
    balanced  rk4, dt = limit / 4        ~1e-4 rad   (the default: on the measured Pareto front)
    exact     dop853 (adaptive, PI step control, steps landing on the force law's kinks), tol = 1e-8, and
              beta_geometry = "geometric" (the full docs/physics.md#band-torque band geometry): ~1e-10 rad on the
              small-angle scene; a scene that sets a fixed stepper gets dt = limit / 32 instead
hil (the firmware's control rate is the model's clock; plant steps per control tick):
    fast      symplectic_euler, 1 step per tick   ~1-2 encoder counts from the converged loop over 3 s
    balanced  the same (the default): nothing cheaper exists, the loop's own quantisation dominates, and
              the served emulator (bus/serve) and bench-speed run exactly this loop
    exact     rk4, 2 steps per tick, geometric beta   2.9e-3 rad from 64 steps per tick with the geometric form
              (small-angle form: converged, 2e-7 rad)
image (the flashed images; the plant steps per 50 us window, steps chosen from the stable limit):
    the hil presets' stepper and beta geometry (fast, balanced: symplectic_euler; exact: rk4, geometric beta)
continuum: the knob sets nothing (models/continuum.py runs scipy BDF at its own tolerance).

Cost: exact is the dearest level except where a lattice scene sets the small-angle beta itself
(exp3_single_sigma9, _sigma6: dop853 alone, cheaper than balanced); docs/accuracy.md#tiers has each shipped
scene's cost per level. record() is what summary.json says of a run's accuracy (the options the preset changed,
with the values they ran with, and the error estimate that `run` prints).
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

from .models import make_model
from .models.options import DEFAULT_TOL
from .models.steppers import STEPPERS

if TYPE_CHECKING:
    pass

LEVELS = ("fast", "balanced", "exact")
DEFAULT = "balanced"

# (stepper, fraction of the stable limit for a fixed-step stepper, tol for an adaptive one, beta_geometry or None)
LATTICE = {
    "fast": ("rk4", 0.8, None, None),
    "balanced": ("rk4", 0.25, None, None),
    "exact": ("dop853", 1 / 32, 1e-8, "geometric"),
}
# (stepper, plant steps per control tick, beta_geometry or None)
HIL = {
    "fast": ("symplectic_euler", 1, None),
    "balanced": ("symplectic_euler", 1, None),
    "exact": ("rk4", 2, "geometric"),
}

KNOB_KEYS = ("stepper", "dt", "tol", "substeps", "beta_geometry")


def check_level(level: object) -> str:
    if level not in LEVELS:
        from .models.options import ConfigError

        raise ConfigError(f"accuracy = {level!r}: expected one of {', '.join(LEVELS)}")
    return level


def _preset(options, stepper, geom, explicit):
    """The preset's stepper and beta geometry on every key the scene did not set."""
    kw = {}
    if "stepper" not in explicit:
        kw["stepper"] = stepper
    if geom and "beta_geometry" not in explicit and options.bands == "cubic":
        kw["beta_geometry"] = geom
    return dataclasses.replace(options, **kw)


def _resolve_lattice(params, perturbations, options, level, explicit):
    stepper, frac, tol, geom = LATTICE[level]
    opts = _preset(options, stepper, geom, explicit)
    if STEPPERS[opts.stepper].adaptive:
        # the tolerance sets the accuracy; dt (a cap on the step) only where the scene sets it
        if "tol" not in explicit:
            opts = dataclasses.replace(opts, tol=tol if tol is not None else DEFAULT_TOL)
    elif "dt" not in explicit:
        limit, _ = make_model("lattice", params, perturbations, opts).step_limit()
        opts = dataclasses.replace(opts, dt=frac * limit)
    return opts


def _resolve_hil(params, perturbations, options, level, explicit):
    import math

    stepper, subs, geom = HIL[level]
    opts = _preset(options, stepper, geom, explicit)
    if "substeps" not in explicit and "dt" not in explicit:
        m = make_model("hil", params, perturbations, opts)
        limit, _ = m.step_limit()
        tick = 1.0 / m.rate_hz
        # never above 0.8 x the stable limit (slow control rates need several plant steps per tick)
        opts = dataclasses.replace(opts, substeps=max(subs, math.ceil(tick / (0.8 * limit) - 1e-9)))
    return opts


def _resolve_image(params, perturbations, options, level, explicit):
    stepper, _subs, geom = HIL[level]
    return _preset(options, stepper, geom, explicit)


# model name -> its preset rule; a model without one (the continuum) keeps its options
RESOLVERS = {"lattice": _resolve_lattice, "hil": _resolve_hil, "image": _resolve_image}


def resolve_options(model: str, params, perturbations, options, level: str, explicit=()):
    """ModelOptions with the preset of `level` applied to every knob key not in `explicit`."""
    check_level(level)
    rule = RESOLVERS.get(model)
    return options if rule is None else rule(params, perturbations, options, level, set(explicit))


def record(model: str, level: str, scene_options, ran_options, explicit=(), preset_options=None) -> dict:
    """summary.json's "accuracy": the level, every knob the preset changed with the value it ran with
    (preset_changed), the knobs the scene set itself (scene_set: they beat the preset), and the error estimate of
    what ran (error_estimate; the preset's figure only where no knob the scene set differs from the preset's own
    value, preset_options: the options the preset alone gives)."""
    changed = {k: getattr(ran_options, k) for k in KNOB_KEYS if getattr(ran_options, k) != getattr(scene_options, k)}
    scene_set = sorted(k for k in explicit if k in KNOB_KEYS)
    differs = [k for k in scene_set if preset_options is None or getattr(preset_options, k) != getattr(ran_options, k)]
    return {
        "level": level,
        "preset_changed": changed,
        "scene_set": scene_set,
        "error_estimate": error_estimate(model, level, differs),
    }


def error_estimate(model: str, level: str, scene_set=()) -> dict:
    """The measured errors of a run at `level` (host_emulator/tiers.py, docs/accuracy.md#tiers): integration_rad,
    max |alpha - the same tier and components at a converged step| (None where not measured, or where the scene
    sets a knob itself so the preset's figure does not apply), and vs_next_tier_rad, max |alpha - the next tier
    up|; both on the default scene over 3 s."""
    from .tiers import ERROR_VS_UP_RAD, PRESET_ERROR_RAD, UP

    integ = None if scene_set else PRESET_ERROR_RAD.get((model, level))
    return {
        "integration_rad": integ,
        "next_tier": UP.get(model),
        "vs_next_tier_rad": ERROR_VS_UP_RAD.get(model),
        "measured_on": "default scene, 3 s (python -m host_emulator.benchmarks.tiers)",
        **({"note": f"the scene sets {', '.join(scene_set)} itself: no preset figure"} if scene_set else {}),
    }


def estimate_line(acc: dict) -> str:
    """One line for `run`: the level and the error estimate of summary.json's "accuracy"."""
    e = acc["error_estimate"]
    parts = []
    if e["integration_rad"] is not None:
        parts.append(f"integration ~{e['integration_rad']:.2g} rad against a converged step")
    elif e.get("note"):
        parts.append(e["note"])
    else:
        parts.append("integration error not measured for this tier")
    if e["vs_next_tier_rad"] is not None:
        parts.append(f"~{e['vs_next_tier_rad']:.2g} rad from the {e['next_tier']} tier")
    return (
        f"  accuracy {acc['level']}: error estimate (max angle, measured on the default scene over 3 s): "
        + "; ".join(parts)
    )
