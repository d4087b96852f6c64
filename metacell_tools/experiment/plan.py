"""Scene -> the rig's command plan: firmware parameters (wire units), perturbation commands, what the rig cannot set.

Everything here is checked before the rig is touched: a scene that loads but cannot be
expressed in the firmware's commands (torque or duration outside the PERTURB payload,
a cell the bus does not address) raises PlanError naming the key.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

from host_emulator.params import Params
from metacell_common.cli import cells_text
from metacell_tools.rigtools import proto
from metacell_tools.rigtools.command import CTRL_RATE_HZ
from protocol import codec

if TYPE_CHECKING:
    from host_emulator.scene import Scene

RIG_PWM_TOP = 2400  # TCC0 period of the cell build (docs/hardware.md, MC_PWM_TOP)
# scene params the runner sends to every cell: Params field -> register (values SI: N*m/rad, rad)
FIRMWARE_PARAMS = (("k_ab", "K_AB"), ("sigma", "SIGMA"), ("alpha_star", "ASTAR"), ("k1", "K1"), ("k2", "K2"))
# set through PWM_LIMIT / BEMF; everything else in Params is the plant or the build, not settable at run time
CONTROL_PARAMS = ("vmax_v", "bemf_comp")


class PlanError(ValueError):
    """The scene cannot be run on the rig as written (raised before any frame is sent)."""


@dataclass(frozen=True)
class Command:
    reg: str
    values: dict
    label: str
    cells: tuple[int, ...] | None = None  # the cells it goes to (None: every cell of the plan)


@dataclass(frozen=True)
class PerturbCommand:
    start_s: float  # after the drive is enabled
    cell: int
    values: dict  # PERTURB payload, raw register values: chain, torque (wire torque LSBs), ticks
    label: str


@dataclass
class ExperimentPlan:
    cells: list[int]
    setup: list[Command]
    perturbations: list[PerturbCommand]
    t_end_s: float
    ctrl_rate_hz: int
    last_perturbation_end_s: float
    not_settable: dict = field(default_factory=dict)  # param -> scene value differing from the rig build's default
    topology: dict | None = None  # the rig's topology (Topology.as_dict) when not the rig as built (a chain of 16)

    def as_dict(self) -> dict:
        return {
            "cells": self.cells,
            "ctrl_rate_hz": self.ctrl_rate_hz,
            "t_end_s": self.t_end_s,
            "setup": [
                {"reg": c.reg, **c.values, "label": c.label, **({"cells": list(c.cells)} if c.cells else {})}
                for c in self.setup
            ],
            "perturbations": [
                {"start_s": p.start_s, "cell": p.cell, **p.values, "label": p.label} for p in self.perturbations
            ],
            "not_settable": self.not_settable,
            **({"topology": self.topology} if self.topology is not None else {}),
        }


def wire_param(name: str, value: float) -> int:
    """SI -> register value of a reaction parameter (protocol.codec: uN*m/rad, urad). Only values the register
    cannot carry are refused here: the cells judge the rest (a refusal aborts the run before the drive is on)."""
    reg = dict(FIRMWARE_PARAMS).get(name)
    if reg is None:
        raise PlanError(f"params.{name}: not a firmware parameter (one of {[n for n, _ in FIRMWARE_PARAMS]})")
    try:
        return codec.to_register(reg, "value", value, firmware=False)
    except codec.RangeError as e:
        raise PlanError(f"params.{name} = {value!r}: {e}") from None


def param_commands(name: str, reg: str, p: Params) -> list[Command]:
    """The register writes of one reaction parameter: one command for every cell when the value is the same for
    all, else one per distinct value with the cells that take it (a per-cell scene: each cell gets its own)."""
    if name not in p.per_cell_keys:
        v = p.value(name)
        return [Command(reg, {"value": wire_param(name, v)}, f"{name} = {v:.6g}")]
    vals = p.per_cell(name)
    groups: dict[int, list[int]] = {}
    for j, v in enumerate(vals, start=1):
        try:
            raw = wire_param(name, float(v))
        except PlanError as e:
            raise PlanError(f"params.{name}[{j}] (cell {j}): {e}") from None
        groups.setdefault(raw, []).append(j)
    return [
        Command(reg, {"value": raw}, f"{name} = {vals[js[0] - 1]:.6g} (cells {cells_text(js)})", tuple(js))
        for raw, js in groups.items()
    ]


def pwm_limit_ticks(p: Params, pwm_top: int = RIG_PWM_TOP) -> int:
    """Duty limit for the scene's motor voltage cap: ticks = round(min(vmax_v, supply_v) / supply_v * pwm_top).

    The cell clamps it again to its own 5.86 V cap (mc_drive_set_limit)."""
    return round(min(p.vmax_v, p.supply_v) / p.supply_v * pwm_top)


def perturb_payload(chain: str, torque_Nm: float, duration_s: float, rate_hz: int, where: str) -> dict:
    """PERTURB payload (raw): torque in wire LSBs (protocol.codec), ticks = round(duration_s * rate_hz) >= 1."""
    try:
        torque = codec.to_register("PERTURB", "torque", torque_Nm)
    except codec.RangeError as e:
        raise PlanError(f"{where}.torque_Nm = {torque_Nm}: {e}") from None
    ticks = max(1, round(duration_s * rate_hz))
    t_max = codec.raw_range("PERTURB", "ticks")[1]
    if ticks > t_max:
        raise PlanError(
            f"{where}.duration_s = {duration_s}: at most {t_max / rate_hz:.3f} s ({t_max} ticks at {rate_hz} Hz)"
        )
    return {"chain": 0 if chain == "alpha" else 1, "torque": torque, "ticks": ticks}


def make_plan(
    scene: Scene,
    *,
    t_end_s: float | None = None,
    ctrl_rate_hz: int = CTRL_RATE_HZ,
    pwm_top: int = RIG_PWM_TOP,
    pwm_limit: int | None = None,
    rig_cells: int = proto.N_CELLS,
    topology: dict | None = None,
) -> ExperimentPlan:
    """The commands that run `scene` on the rig of `rig_cells` cells (PlanError if the scene cannot be expressed);
    topology: the rig's (Topology.as_dict()) when it is not the rig as built, recorded in the plan."""
    if not 1 <= scene.cells <= rig_cells:
        raise PlanError(f"cells = {scene.cells}: the rig has {rig_cells} cells")
    t_end = scene.t_end_s if t_end_s is None else float(t_end_s)
    if not (math.isfinite(t_end) and t_end > 0):
        raise PlanError(f"--t-end {t_end_s!r}: expected a positive number of seconds")
    p = scene.params
    setup = [Command("ENABLE", {"on": 0}, "drive off while configuring")]
    for name, reg in FIRMWARE_PARAMS:
        setup += param_commands(name, reg, p)
    lim = pwm_limit_ticks(p, pwm_top) if pwm_limit is None else int(pwm_limit)
    if not 0 <= lim <= pwm_top:
        raise PlanError(f"PWM limit {lim} ticks: expected 0..{pwm_top}")
    setup.append(Command("PWM_LIMIT", {"ticks": lim}, f"PWM limit {lim}/{pwm_top} ticks"))
    setup.append(
        Command("BEMF", {"on": int(bool(p.bemf_comp))}, f"back-EMF compensation {'on' if p.bemf_comp else 'off'}")
    )
    setup.append(Command("CLEAR_FAULTS", {}, "clear latched faults"))
    perts = []
    for i, q in enumerate(scene.perturbations):
        where = f"perturbation[{i + 1}]"
        perts.append(
            PerturbCommand(
                float(q.start_s),
                int(q.cell),
                perturb_payload(q.chain, q.torque_Nm, q.duration_s, ctrl_rate_hz, where),
                f"{q.chain}_{q.cell} {q.torque_Nm * 1e3:+.1f} mN*m for {q.duration_s:g} s",
            )
        )
    perts.sort(key=lambda c: (c.start_s, c.cell))
    last = max([q.start_s + q.duration_s for q in scene.perturbations], default=0.0)
    base = Params(cells=scene.cells)
    skip = {n for n, _ in FIRMWARE_PARAMS} | set(CONTROL_PARAMS) | {"cells", "shape", "lattice", "boundary"}
    not_settable = {
        f.name: getattr(p, f.name)
        for f in dataclasses.fields(Params)
        if f.name not in skip and getattr(p, f.name) != getattr(base, f.name)
    }
    if round(p.control_rate_hz) != ctrl_rate_hz:
        not_settable["control_rate_hz"] = p.control_rate_hz
    if p.pwm_top != pwm_top:
        not_settable["pwm_top"] = p.pwm_top
    return ExperimentPlan(
        list(range(1, scene.cells + 1)), setup, perts, t_end, ctrl_rate_hz, float(last), not_settable, topology
    )
