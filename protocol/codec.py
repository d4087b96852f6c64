"""SI <-> register units of every register field, driven by the units and limits in protocol/definition.py.

    to_register("K_AB", "value", 0.072)        -> 72000          (uN*m/rad; RangeError outside the firmware's range)
    to_register("PERTURB", "torque", 0.02)     -> 5000           (wire torque LSBs)
    from_register("PERTURB", "torque", 5000)   -> 0.02           (N*m)
    encode("PERTURB", chain=0, torque=0.02, ticks=200) -> raw payload values for protocol.wire.pack_payload

Micro-units convert as round(x * 1e6 / micro): with micro = 1 that is exactly round(x * 1e6), the scaling the
emulator's firmware configuration has always used (its trajectories stay bit-identical).
"""

from __future__ import annotations

import math
import numbers

from . import definition as D
from .wire import REGISTERS, TYPE_RANGES

COUNTS_PER_REV = D.COUNTS_PER_REV
RAD_PER_COUNT = 2 * math.pi / COUNTS_PER_REV
COUNTS_PER_RAD = COUNTS_PER_REV / (2 * math.pi)
TORQUE_WIRE_UNM = D.TORQUE_WIRE_UNM
LIMITS = dict(D.LIMITS)
PERTURB_MAX_NM = D.LIMITS["PERTURB_MAX_UNM"] * 1e-6  # largest |perturbing torque| the firmware accepts, N*m
K_MAX_NM_PER_RAD = D.LIMITS["K_MAX_UNM"] * 1e-6
ASTAR_MAX_RAD = D.LIMITS["ASTAR_MAX_URAD"] * 1e-6


class RangeError(ValueError):
    """A value the register cannot carry or the firmware would refuse (nothing was sent)."""


def lsb(unit: str | None) -> float:
    """SI value of one LSB of `unit` (1 for unitless fields)."""
    if unit is None:
        return 1.0
    u = D.UNITS[unit]
    return u["micro"] * 1e-6 if "micro" in u else float(u["lsb"])


def si_unit(unit: str | None) -> str:
    return "" if unit is None else D.UNITS[unit]["si"]


def unit_text(unit: str | None) -> str:
    """How the docs name a unit ('4 uN*m', 'count, 400/rev', ...)."""
    return "" if unit is None else D.UNITS[unit].get("text", unit)


def si_to_raw(unit: str | None, x: float) -> int:
    """round(x / LSB) for an SI value x (ValueError if x is not finite). No range check."""
    if isinstance(x, bool) or not isinstance(x, numbers.Real) or not math.isfinite(x):
        raise RangeError(f"not a finite number: {x!r}")
    if unit is None:
        return round(x)
    u = D.UNITS[unit]
    return round(x * 1e6 / u["micro"]) if "micro" in u else round(x / u["lsb"])


def raw_to_si(unit: str | None, raw: int) -> float:
    """SI value of a raw register/signal value."""
    if unit is None:
        return float(raw)
    u = D.UNITS[unit]
    return raw * u["micro"] * 1e-6 if "micro" in u else raw * u["lsb"]


def _field(reg: str, name: str) -> tuple[str, str | None]:
    if reg not in REGISTERS:
        raise RangeError(f"unknown register {reg!r}; one of {sorted(REGISTERS)}")
    for f in REGISTERS[reg]["payload"]:
        if f[0] == name:
            return f[1], f[2]
    raise RangeError(f"register {reg} has no field {name!r} (fields: {[f[0] for f in REGISTERS[reg]['payload']]})")


def unit_of(reg: str, name: str) -> str | None:
    """Unit key (definition UNITS) of a register field, None for unitless fields."""
    return _field(reg, name)[1]


def raw_range(reg: str, name: str, firmware: bool = True) -> tuple[int, int]:
    """Accepted raw values of a field: its type's range, narrowed by the definition's firmware range (unless
    firmware=False: then only what the field can carry)."""
    typ, _ = _field(reg, name)
    lo, hi = TYPE_RANGES[typ]
    if not firmware:
        return lo, hi
    rlo, rhi = REGISTERS[reg].get("range", {}).get(name, (lo, hi))
    return max(lo, rlo), min(hi, rhi)


def si_range(reg: str, name: str, firmware: bool = True) -> tuple[float, float]:
    """raw_range in SI units."""
    _, unit = _field(reg, name)
    lo, hi = raw_range(reg, name, firmware)
    return raw_to_si(unit, lo), raw_to_si(unit, hi)


def to_register(reg: str, name: str, x: float, firmware: bool = True) -> int:
    """SI value -> raw register value, RangeError (naming the accepted SI range) if the firmware would refuse
    it; with firmware=False only if the field cannot carry it (the cell then answers RESULT RANGE itself)."""
    _, unit = _field(reg, name)
    raw = si_to_raw(unit, x)
    lo, hi = raw_range(reg, name, firmware)
    if not lo <= raw <= hi:
        slo, shi = si_range(reg, name, firmware)
        u = si_unit(unit)
        who = "the firmware accepts" if firmware else f"the {_field(reg, name)[0]} field carries"
        raise RangeError(f"{reg}.{name} = {x:g} {u}: {who} {slo:g}..{shi:g} {u}".rstrip())
    return raw


def from_register(reg: str, name: str, raw: int) -> float:
    _, unit = _field(reg, name)
    return raw_to_si(unit, raw)


def encode(reg: str, **si) -> dict:
    """Raw payload values of `reg` from SI values (every field required; RangeError otherwise)."""
    names = [f[0] for f in REGISTERS[reg]["payload"]] if reg in REGISTERS else []
    if reg not in REGISTERS or set(names) != set(si):
        raise RangeError(f"register {reg}: payload fields are {names}, got {sorted(si)}")
    return {n: to_register(reg, n, si[n]) for n in names}


def decode(reg: str, raw: dict) -> dict:
    """SI values of a raw payload dict."""
    return {n: from_register(reg, n, v) for n, v in raw.items()}


def counts_to_rad(counts):
    """Encoder counts -> rad (works on numbers and numpy arrays)."""
    return counts * RAD_PER_COUNT
