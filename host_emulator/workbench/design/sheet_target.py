"""A design's input on a sheet: its size, the region that must rest, an optional stripe wavelength, the pushes."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from metacell_common.outpaths import show

from ...topology import Topology
from .target import DesignError


@dataclass(frozen=True)
class SheetTarget:
    """A square sheet of `shape` (rows, cols): the `rest` cells (1-based, row-major) end at rest, every other cell
    (the pattern region) holds a pattern; `lam`: its dominant wavelength in cells (None: any wavelength)."""

    shape: tuple[int, int]
    rest: tuple[int, ...]
    lam: float | None = None
    rest_text: str = ""

    @property
    def topology(self) -> Topology:
        return Topology(self.shape, "square", False)

    @property
    def cells(self) -> int:
        return self.shape[0] * self.shape[1]

    def text(self) -> str:
        t = f"lambda={self.lam:g}" if self.lam is not None else "pattern"
        return f"{t} rest={self.rest_text}" if self.rest_text else t

    def rest_mask(self) -> np.ndarray:
        """(n,) bool in cell order: True on the rest region."""
        m = np.zeros(self.cells, dtype=bool)
        m[[c - 1 for c in self.rest]] = True
        return m

    def segments(self) -> np.ndarray:
        """Segment of every cell (0-based): 0 the pattern region, 1 the rest region (a per-cell parameter takes one
        value per segment, as a chain's per domain)."""
        return self.rest_mask().astype(int)

    def pattern_box(self) -> tuple[slice, slice] | None:
        """(row slice, col slice) of the pattern region when it is a rectangle (0-based), else None."""
        g = ~self.rest_mask().reshape(self.shape)
        rr, cc = np.nonzero(g)
        box = (slice(int(rr.min()), int(rr.max()) + 1), slice(int(cc.min()), int(cc.max()) + 1))
        return box if bool(g[box].all()) else None


def parse_shape(text: str) -> tuple[int, int]:
    """`16x16` (rows x cols), each 2..256."""
    a, sep, b = str(text).lower().partition("x")
    try:
        rows, cols = int(a), int(b)
    except ValueError:
        raise DesignError(f"--sheet {show(repr(text))}: expected ROWSxCOLS such as 16x16") from None
    if not sep or not (2 <= rows <= 256 and 2 <= cols <= 256):
        raise DesignError(f"--sheet {show(repr(text))}: expected ROWSxCOLS, each in 2..256")
    return rows, cols


def _span(text: str, top: int, what: str, whole: str) -> range:
    lo, sep, hi = text.strip().partition("-")
    try:
        a, b = (int(lo), int(hi)) if sep else (int(lo), int(lo))
    except ValueError:
        raise DesignError(f"--rest {show(repr(whole))}: {what} {show(repr(text))} is not N or N-M") from None
    if not 1 <= a <= b <= top:
        raise DesignError(f"--rest {show(repr(whole))}: {what} {show(text)} must lie in 1..{top}")
    return range(a, b + 1)


def parse_region(text: str, shape: tuple[int, int]) -> tuple[int, ...]:
    """`rows=1-8`, `cols=9-16` or a rectangle `ROWSxCOLS` such as `1-8x9-16`; several joined by `+`. The cells
    (1-based, row-major) of their union."""
    rows, cols = shape
    top = Topology(shape, "square", False)
    out: set[int] = set()
    parts = [p.strip() for p in str(text).split("+")]
    if not text or not all(parts):
        raise DesignError(f"--rest {show(repr(text))}: expected rows=A-B, cols=A-B or A-BxC-D (joined by +)")
    for part in parts:
        key, sep, val = part.partition("=")
        if sep and key.strip().lower() in ("rows", "row"):
            rr, cc = _span(val, rows, "rows", text), range(1, cols + 1)
        elif sep and key.strip().lower() in ("cols", "col"):
            rr, cc = range(1, rows + 1), _span(val, cols, "cols", text)
        elif not sep and "x" in part.lower():
            r, _, c = part.lower().partition("x")
            rr, cc = _span(r, rows, "rows", text), _span(c, cols, "cols", text)
        else:
            raise DesignError(f"--rest {show(repr(text))}: expected rows=A-B, cols=A-B or A-BxC-D (joined by +)")
        out |= {top.cell_of(r, c) for r in rr for c in cc}
    if len(out) == rows * cols:
        raise DesignError(f"--rest {show(repr(text))}: covers the whole sheet; leave a region to pattern")
    return tuple(sorted(out))


def parse_sheet_target(text: str, shape: tuple[int, int], rest: str | None) -> SheetTarget:
    """`pattern` (any pattern) or `lambda=N` (stripes of wavelength N cells, 2 <= N <= twice the sheet's longer
    side) in the pattern region; `rest`: parse_region's text (required: a sheet target is a region that patterns
    beside one that rests)."""
    if not rest:
        raise DesignError("--rest: a sheet's target needs the region that rests (rows=A-B, cols=A-B or A-BxC-D)")
    cells = parse_region(rest, shape)
    key, sep, val = str(text).strip().partition("=")
    key = key.strip().lower()
    if key == "pattern" and not sep:
        return SheetTarget(shape, cells, None, rest.replace(" ", ""))
    if key != "lambda" or not sep:
        raise DesignError(f"--target {show(repr(text))}: on a sheet expected pattern or lambda=N (cells)")
    try:
        lam = float(val)
    except ValueError:
        raise DesignError(f"--target {show(repr(text))}: lambda must be a number of cells") from None
    if not (math.isfinite(lam) and 2 <= lam <= 2 * max(shape)):
        raise DesignError(f"--target {show(repr(text))}: lambda must lie in 2..{2 * max(shape)} cells on this sheet")
    return SheetTarget(shape, cells, lam, rest.replace(" ", ""))


@dataclass(frozen=True)
class SheetPush:
    row: int
    col: int
    sign: int  # +1 CCW, -1 CW


def parse_sheet_pushes(text: str, target: SheetTarget) -> tuple[SheetPush, ...]:
    """`ROWxCOL[:SIGN],...` such as `8x4` or `4x4,12x4:-`: hand pushes on alpha of those cells, each in the pattern
    region (a push on the rest region would test the rest law, not the pattern)."""
    rows, cols = target.shape
    rest = set(target.rest)
    top = target.topology
    out: list[SheetPush] = []
    for part in (p.strip() for p in str(text).split(",") if p.strip()):
        rc, _, s = part.partition(":")
        r, sep, c = rc.lower().partition("x")
        try:
            row, col = int(r), int(c)
        except ValueError:
            raise DesignError(f"--push {show(repr(text))}: expected ROWxCOL[:SIGN],... such as 8x4") from None
        if not sep or not (1 <= row <= rows and 1 <= col <= cols):
            raise DesignError(f"--push {show(repr(text))}: cell {show(rc)} outside the {rows} x {cols} sheet")
        if top.cell_of(row, col) in rest:
            raise DesignError(
                f"--push {show(repr(text))}: cell {row}x{col} lies in the rest region; push the pattern's"
            )
        sign = {"": 1, "+": 1, "ccw": 1, "-": -1, "cw": -1}.get(s.strip().lower())
        if sign is None:
            raise DesignError(f"--push {show(repr(text))}: sign {show(repr(s))}: expected + (CCW) or - (CW)")
        out.append(SheetPush(row, col, sign))
    if not out or len({(p.row, p.col) for p in out}) != len(out):
        raise DesignError(f"--push {show(repr(text))}: expected distinct cells ROWxCOL")
    return tuple(out)
