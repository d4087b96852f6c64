"""Registry of the compiled plant's time steppers by name (C: host_emulator/csrc/he_step.h ids, a file per method)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any


@dataclass(frozen=True)
class StepperInfo:
    name: str
    cid: str  # name of the HE_STEP_* constant in the compiled module
    order: int
    description: str
    adaptive: bool = False  # the lattice runs it with error control (model_options.tol), he_dop853.h


STEPPERS: dict[str, StepperInfo] = {}


def register(info: StepperInfo) -> StepperInfo:
    """Add a stepper to the registry (its C implementation must exist under `cid`)."""
    if info.name in STEPPERS:
        raise ValueError(f"stepper {info.name!r} registered twice")
    STEPPERS[info.name] = info
    return info


register(StepperInfo("euler", "HE_STEP_EULER", 1, "explicit Euler (conditionally stable; reference only)"))
register(
    StepperInfo(
        "symplectic_euler",
        "HE_STEP_SYMPLECTIC",
        1,
        "semi-implicit Euler: velocity first with implicit damping, then position",
    )
)
register(StepperInfo("rk4", "HE_STEP_RK4", 4, "classical fourth-order Runge-Kutta"))
register(
    StepperInfo(
        "noh_bathe", "HE_STEP_NOH_BATHE", 2, "Noh-Bathe two-sub-step explicit (p = 0.54), 2 force evaluations per step"
    )
)
register(
    StepperInfo(
        "imex_euler",
        "HE_STEP_IMEX",
        1,
        "linearly implicit Euler: bands + damping implicit (tridiagonal per chain), reaction explicit",
    )
)

register(
    StepperInfo(
        "dop853",
        "HE_STEP_DOP853",
        8,
        "Dormand-Prince 8(5,3), 12 force evaluations per step: adaptive with PI step control in the lattice "
        "(model_options.tol), fixed steps in the hil loop",
        adaptive=True,
    )
)

DEFAULT_STEPPER = "symplectic_euler"


def stepper_id(lib: Any, name: str) -> int:
    """The compiled id of a registered stepper; ValueError naming the known ones otherwise."""
    try:
        info = STEPPERS[name]
    except KeyError:
        raise ValueError(f"unknown stepper {name!r}; known: {', '.join(sorted(STEPPERS))}") from None
    return int(getattr(lib, info.cid))
