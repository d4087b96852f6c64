"""Lattice topology as data: which cells exist and which pairs of them a band joins (a chain, a ring, a sheet).

A topology is its cells and its bonds, nothing else; every model, observable, plot and dataset asks it rather
than assuming a chain. Cells are numbered 1..n as on the rig; a sheet's cell numbers run row by row:

    cell = (row - 1) * cols + col          (row 1..rows, col 1..cols, both 1-based like cell numbers)

Bonds are 0-based index pairs (i, j), i the cell the bond leaves, in a fixed order:

* chain: (j, j+1) for j = 0..n-2 (the order every golden digest was recorded with); a ring adds (n-1, 0);
* square sheet: for each cell in row-major order, its bond to the right (axis 0), then down (axis 1);
  periodic sheets wrap both;
* hexagonal sheet (a rhombus in axial coordinates: six neighbours per inner cell): right (axis 0), down
  (axis 1), down-left (axis 2).

The discrete Laplacian of the topology (degree minus adjacency) has, on a periodic lattice, the symbol

    chain        L(k)      = 2 (1 - cos k)
    square       L(kx, ky) = 2 (2 - cos kx - cos ky)
    hexagonal    L(k1, k2) = 2 (3 - cos k1 - cos k2 - cos(k1 - k2))   (k1, k2 along the axial directions)

(wavevectors in radians per cell spacing), whose small-k limit is |k|^2 (square; 3/2 |k|^2 in the hexagonal
lattice's own metric); the continuum's symbol is |k|^2, isotropic.
"""

from __future__ import annotations

import functools
import math
from dataclasses import dataclass

import numpy as np

KINDS = ("chain", "square", "hex")
BOUNDARIES = ("open", "periodic")


class TopologyError(ValueError):
    """A lattice that cannot be built (one line naming the bad value)."""


@dataclass(frozen=True)
class Topology:
    """A lattice's cells and bonds. shape (n,) for a chain, (rows, cols) for a sheet."""

    shape: tuple[int, ...]
    kind: str = "chain"
    periodic: bool = False

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise TopologyError(f"lattice {self.kind!r}: expected one of {', '.join(KINDS)}")
        want = 1 if self.kind == "chain" else 2
        if len(self.shape) != want or not all(isinstance(s, int) and s >= 1 for s in self.shape):
            raise TopologyError(
                f"cells = {list(self.shape)}: a {self.kind} needs "
                + ("one whole number of cells" if want == 1 else "[rows, cols], two whole numbers >= 1")
            )
        if self.periodic and self.kind == "chain" and self.shape[0] < 3:
            raise TopologyError(f"a ring needs at least 3 cells (cells = {self.shape[0]})")
        if self.periodic and self.kind != "chain" and min(self.shape) < 3:
            raise TopologyError(f"a periodic sheet needs at least 3 rows and 3 columns (cells = {list(self.shape)})")

    # ---- construction --------------------------------------------------------------------------------
    @staticmethod
    def chain(n: int, periodic: bool = False) -> Topology:
        return Topology((int(n),), "chain", periodic)

    @staticmethod
    def from_spec(cells, lattice: str | None = None, boundary: str = "open") -> Topology:
        """The topology of a scene's `cells` (n, or [rows, cols]), `lattice` ("square" default for a sheet,
        "hex"; "chain" for a number) and `boundary` ("open" or "periodic")."""
        if boundary not in BOUNDARIES:
            raise TopologyError(f"boundary = {boundary!r}: expected one of {', '.join(BOUNDARIES)}")
        periodic = boundary == "periodic"
        if isinstance(cells, (list, tuple)):
            if len(cells) == 1:
                cells = cells[0]
            else:
                shape = tuple(cells)
                if any(isinstance(s, bool) or not isinstance(s, int) for s in shape):
                    raise TopologyError(f"cells = {list(shape)}: expected whole numbers")
                kind = lattice or "square"
                if kind == "chain":
                    raise TopologyError(f"lattice = 'chain' with cells = {list(shape)}: a chain's cells is one number")
                return Topology(shape, kind, periodic)
        if isinstance(cells, bool) or not isinstance(cells, int):
            raise TopologyError(f"cells = {cells!r}: expected a whole number or [rows, cols]")
        if lattice not in (None, "chain"):
            raise TopologyError(f"lattice = {lattice!r} needs cells = [rows, cols]")
        return Topology((cells,), "chain", periodic)

    # ---- sizes -----------------------------------------------------------------------------------------
    @property
    def n(self) -> int:
        return math.prod(self.shape)

    @property
    def ndim(self) -> int:
        return len(self.shape)

    @property
    def rows(self) -> int:
        return self.shape[0] if self.ndim == 2 else 1

    @property
    def cols(self) -> int:
        return self.shape[-1]

    @property
    def is_sheet(self) -> bool:
        return self.ndim == 2

    @property
    def is_open_chain(self) -> bool:
        """The chain every compiled fast path was written for: bonds (j, j+1) only."""
        return self.kind == "chain" and not self.periodic

    @property
    def boundary(self) -> str:
        return "periodic" if self.periodic else "open"

    @property
    def cells_spec(self):
        """What a scene writes for these cells: n for a chain, [rows, cols] for a sheet."""
        return self.shape[0] if self.ndim == 1 else list(self.shape)

    def describe(self) -> str:
        if self.kind == "chain":
            return f"{'ring' if self.periodic else 'chain'} of {self.n} cells"
        name = "square" if self.kind == "square" else "hexagonal"
        return f"{self.rows} x {self.cols} {name} sheet ({self.n} cells, {self.boundary} edges)"

    def as_dict(self) -> dict:
        return {"cells": self.cells_spec, "lattice": self.kind, "boundary": self.boundary}

    # ---- numbering ---------------------------------------------------------------------------------------
    def cell_of(self, row: int, col: int) -> int:
        """1-based cell number of (row, col), both 1-based; IndexError outside the sheet."""
        if not (1 <= row <= self.rows and 1 <= col <= self.cols):
            raise IndexError(f"(row {row}, col {col}) outside the {self.rows} x {self.cols} sheet")
        return (row - 1) * self.cols + col

    def row_col(self, cell: int) -> tuple[int, int]:
        """(row, col), 1-based, of 1-based cell number `cell`."""
        if not 1 <= cell <= self.n:
            raise IndexError(f"cell {cell} outside 1..{self.n}")
        return (cell - 1) // self.cols + 1, (cell - 1) % self.cols + 1

    def grid(self, values: np.ndarray) -> np.ndarray:
        """values (..., n) as (..., rows, cols) (a chain: (..., 1, n))."""
        a = np.asarray(values)
        return a.reshape(*a.shape[:-1], self.rows, self.cols)

    def positions(self) -> np.ndarray:
        """(n, 2) cell centres in units of the cell spacing: x along a row (col - 1), y down the rows (row - 1);
        a hexagonal sheet's rows are sheared by half a cell and spaced sqrt(3)/2."""
        r, c = np.divmod(np.arange(self.n), self.cols)
        if self.kind == "hex":
            return np.column_stack([c + 0.5 * r, r * (math.sqrt(3) / 2)]).astype(float)
        return np.column_stack([c, r]).astype(float)

    # ---- bonds ---------------------------------------------------------------------------------------------
    @property
    def bonds(self) -> np.ndarray:
        """(nbond, 2) int32, 0-based (i, j) pairs in the order of the module docstring."""
        return _bonds(self)[0]

    @property
    def bond_axis(self) -> np.ndarray:
        """(nbond,) int8: 0 along a row, 1 down a column, 2 the hexagonal diagonal (a chain: all 0)."""
        return _bonds(self)[1]

    @property
    def nbond(self) -> int:
        return len(self.bonds)

    def degree(self) -> np.ndarray:
        """(n,) the number of bonds at each cell."""
        return np.bincount(self.bonds.ravel(), minlength=self.n)

    def laplacian(self, weights: np.ndarray | None = None):
        """The graph Laplacian (degree - adjacency) as a scipy CSR matrix, bonds weighted by `weights` (nbond,)."""
        import scipy.sparse as sp

        b = self.bonds
        w = np.ones(len(b)) if weights is None else np.asarray(weights, dtype=float)
        i, j = b[:, 0], b[:, 1]
        a = sp.coo_matrix((np.concatenate([w, w]), (np.concatenate([i, j]), np.concatenate([j, i]))), (self.n,) * 2)
        deg = np.bincount(i, w, self.n) + np.bincount(j, w, self.n)
        return (sp.diags(deg) - a).tocsr()

    # ---- spectrum ----------------------------------------------------------------------------------------
    def symbol(self, k1, k2=0.0):
        """The discrete Laplacian's symbol L(k) of the module docstring (numpy broadcasting; k in rad/cell)."""
        k1 = np.asarray(k1, dtype=float)
        if self.kind == "chain":
            return 2.0 * (1.0 - np.cos(k1))
        k2 = np.asarray(k2, dtype=float)
        if self.kind == "square":
            return 2.0 * (2.0 - np.cos(k1) - np.cos(k2))
        return 2.0 * (3.0 - np.cos(k1) - np.cos(k2) - np.cos(k1 - k2))


@functools.lru_cache(maxsize=64)
def _bonds(t: Topology) -> tuple[np.ndarray, np.ndarray]:
    if t.kind == "chain":
        n = t.n
        pairs = [(j, j + 1) for j in range(n - 1)]
        if t.periodic:
            pairs.append((n - 1, 0))
        b = np.array(pairs, dtype=np.int32).reshape(-1, 2)
        b.setflags(write=False)
        ax = np.zeros(len(b), dtype=np.int8)
        ax.setflags(write=False)
        return b, ax
    rows, cols = t.shape
    steps = [(0, 1), (1, 0)] + ([(1, -1)] if t.kind == "hex" else [])
    out, axes = [], []
    for r in range(rows):
        for c in range(cols):
            for a, (dr, dc) in enumerate(steps):
                r2, c2 = r + dr, c + dc
                if t.periodic:
                    r2, c2 = r2 % rows, c2 % cols
                elif not (0 <= r2 < rows and 0 <= c2 < cols):
                    continue
                i, j = r * cols + c, r2 * cols + c2
                if i == j:
                    continue
                out.append((i, j))
                axes.append(a)
    b = np.array(out, dtype=np.int32).reshape(-1, 2)
    ax = np.array(axes, dtype=np.int8)
    b.setflags(write=False)
    ax.setflags(write=False)
    return b, ax
