"""The search vector: the varied parameters (one value each, or one per domain of the target) in their box, and
the parameters it stands for, rounded to the registers' resolution."""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ...params import Params
from .constants import BOUNDS, LSB_DIGITS
from .target import Target


@dataclass
class Space:
    """The search vector: one value per global parameter, then one per segment of each per-cell parameter."""

    base: Params
    vary: tuple[str, ...]
    per_cell: tuple[str, ...]
    seg: np.ndarray
    names: list[str] = field(default_factory=list)
    bounds: list[tuple[float, float]] = field(default_factory=list)

    def __post_init__(self):
        nseg = int(self.seg.max()) + 1
        for k in self.vary:
            if k in self.per_cell:
                for s in range(nseg):
                    self.names.append(f"{k}[seg {s + 1}]")
                    self.bounds.append(BOUNDS[k])
            else:
                self.names.append(k)
                self.bounds.append(BOUNDS[k])

    def params(self, x: np.ndarray) -> Params:
        """Params of a search vector, rounded to the registers' resolution."""
        nseg = int(self.seg.max()) + 1
        kw: dict[str, Any] = {}
        i = 0
        for k in self.vary:
            if k in self.per_cell:
                vals = np.asarray(x[i : i + nseg])[self.seg]
                kw[k] = tuple(round(float(v), LSB_DIGITS) for v in vals)
                i += nseg
            else:
                kw[k] = round(float(x[i]), LSB_DIGITS)
                i += 1
        return dataclasses.replace(self.base, **kw)

    def x0(self) -> np.ndarray:
        """The base scene's values as a search vector (clipped into the box)."""
        out = []
        for k in self.vary:
            v = self.base.per_cell(k)
            reps = (
                [float(v[self.seg == s].mean()) for s in range(int(self.seg.max()) + 1)]
                if k in self.per_cell
                else [float(v.mean())]
            )
            out += [min(max(r, BOUNDS[k][0]), BOUNDS[k][1]) for r in reps]
        return np.array(out)


def _shape_ok(p: Params) -> bool:
    k1, k2 = p.per_cell("k1"), p.per_cell("k2")
    return bool(np.all(k1 > np.maximum(k2, 0.0) + 1e-3))


def space_for(base: Params, vary, per_cell, target: Target) -> Space:
    return Space(base, tuple(vary), tuple(per_cell), target.segments())
