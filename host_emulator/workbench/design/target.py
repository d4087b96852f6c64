"""The design's input: the target pattern (a wavelength or a layout of domain walls, cells at rest) and the pushes."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from metacell_common.cli import cells_text
from metacell_common.outpaths import show


class DesignError(ValueError):
    """Bad design input (target, push, parameter names); the message names it."""


@dataclass(frozen=True)
class Target:
    """What the pattern must be: `walls` (bond positions j + 0.5) or only their number `z` (a wavelength target),
    and cells that must stay at rest."""

    kind: str  # "lambda" | "walls"
    z: int
    walls: tuple[float, ...] = ()
    lam: float | None = None
    rest: tuple[int, ...] = ()
    cells: int = 16

    def text(self) -> str:
        t = f"lambda={self.lam:g}" if self.kind == "lambda" else "walls=" + ",".join(f"{w:g}" for w in self.walls)
        return t + (f" rest={_cells_text(self.rest)}" if self.rest else "")

    def layout(self) -> tuple[float, ...]:
        """Wall positions: the target's own, or Z walls evenly spread (a wavelength target's reference layout)."""
        if self.kind == "walls":
            return self.walls
        n = self.cells
        return tuple(math.floor(n * (k + 0.5) / self.z) + 0.5 for k in range(self.z))

    def segments(self) -> np.ndarray:
        """Segment index of every cell (0-based): the domains between the layout's walls, each rest run its own."""
        seg = np.zeros(self.cells, dtype=int)
        walls = self.layout()
        for j in range(self.cells):
            seg[j] = sum(1 for w in walls if w < j + 1)
        if self.rest:
            top = seg.max() + 1
            for j in self.rest:
                seg[j - 1] = top
        _, seg = np.unique(seg, return_inverse=True)
        return seg


def _cells_text(cells: Sequence[int]) -> str:
    return cells_text(cells).replace(", ", ",").replace(" ", "")


def _cells_arg(text: str, n: int, what: str) -> tuple[int, ...]:
    out: list[int] = []
    for part in (p.strip() for p in str(text).split(",") if p.strip()):
        lo, sep, hi = part.partition("-")
        try:
            a, b = (int(lo), int(hi)) if sep else (int(lo), int(lo))
        except ValueError:
            raise DesignError(f"{what} {show(repr(text))}: expected cell numbers or ranges such as 9-16") from None
        if not (1 <= a <= b <= n):
            raise DesignError(f"{what} {show(repr(text))}: cells must lie in 1..{n}")
        out += [j for j in range(a, b + 1) if j not in out]
    if not out:
        raise DesignError(f"{what} {show(repr(text))}: no cells")
    return tuple(sorted(out))


def parse_target(text: str, cells: int = 16, rest: str | Sequence[int] | None = None) -> Target:
    """`lambda=N` (N must fit the chain: Z = 2 (cells - 1) / N whole walls) or `walls=a.5,b.5,...`."""
    key, sep, val = str(text).partition("=")
    key = key.strip().lower()
    rest_cells = () if not rest else (_cells_arg(rest, cells, "--rest") if isinstance(rest, str) else tuple(rest))
    if not sep or key not in ("lambda", "walls"):
        raise DesignError(f"--target {show(repr(text))}: expected lambda=N (cells) or walls=A.5,B.5,...")
    if key == "lambda":
        try:
            lam = float(val)
        except ValueError:
            raise DesignError(f"--target {show(repr(text))}: lambda must be a number of cells") from None
        if not (math.isfinite(lam) and lam > 0):
            raise DesignError(f"--target {show(repr(text))}: lambda must be a positive number of cells")
        z = 2 * (cells - 1) / lam
        if rest_cells:
            raise DesignError("--rest: give the walls of the patterned part (walls=...), not a wavelength")
        if z < 0.999 or abs(z - round(z)) > 1e-3 * z or round(z) > cells - 1:
            fits = ", ".join(f"{2 * (cells - 1) / k:.4g}" for k in range(1, cells))
            raise DesignError(
                f"--target lambda={lam:g}: {z:.3g} walls do not fit {cells} cells (lambda = 2 (n - 1) / Z for Z "
                f"walls); the wavelengths that fit: {fits}"
            )
        z = int(round(z))
        return Target("lambda", z, (), 2 * (cells - 1) / z, rest_cells, cells)
    walls: list[float] = []
    for w in val.split(","):
        try:
            x = float(w)
        except ValueError:
            raise DesignError(
                f"--target {show(repr(text))}: {show(repr(w))} is not a bond position such as 5.5"
            ) from None
        if not (abs(x - math.floor(x) - 0.5) < 1e-9 and 1 <= math.floor(x) <= cells - 1):
            raise DesignError(
                f"--target {show(repr(text))}: wall {show(w.strip())} must sit on a bond j.5 between cells j and j+1, "
                f"1 <= j <= {cells - 1}"
            )
        if x in walls:
            raise DesignError(
                f"--target {show(repr(text))}: wall {w.strip()} is given twice (each bond holds one wall at most)"
            )
        walls.append(x)
    walls = sorted(walls)
    for c in rest_cells:
        if any(abs(c - w) < 1 for w in walls):
            raise DesignError(f"--rest: cell {c} borders a wall of the target; rest cells lie outside the pattern")
    return Target("walls", len(walls), tuple(walls), None, rest_cells, cells)


@dataclass(frozen=True)
class Push:
    cell: int
    sign: int  # +1 CCW, -1 CW


def parse_pushes(text: str | Sequence[int], cells: int = 16) -> tuple[Push, ...]:
    """`8`, `6,10`, `1:+,16:-` (CCW + by default): hand pushes on alpha of those cells."""
    if not isinstance(text, str):
        return tuple(Push(int(c), 1) for c in text)
    out = []
    for part in (p.strip() for p in text.split(",") if p.strip()):
        c, _, s = part.partition(":")
        try:
            cell = int(c)
        except ValueError:
            raise DesignError(f"--push {show(repr(text))}: expected CELL[:SIGN],... such as 8 or 1:+,16:-") from None
        if not 1 <= cell <= cells:
            raise DesignError(f"--push {show(repr(text))}: cell {cell} outside 1..{cells}")
        sign = {"": 1, "+": 1, "ccw": 1, "-": -1, "cw": -1}.get(s.strip().lower())
        if sign is None:
            raise DesignError(f"--push {show(repr(text))}: sign {show(repr(s))}: expected + (CCW) or - (CW)")
        out.append(Push(cell, sign))
    if not out or len({p.cell for p in out}) != len(out):
        raise DesignError(f"--push {show(repr(text))}: expected distinct cells")
    return tuple(out)
