"""The kind table of docs/patterns2d.md: how often analysis.pattern2d reads hand-made 2-D fields as what they are.

    python -m host_emulator.benchmarks.pattern2d [--draws 40] [--seed 0]      # about a minute on one core

For each family of fields (stripes, saturated stripes, hexagonal spots, square spots, labyrinths: the generators
below, which the tests use too) and each sheet (16 x 16 open and 32 x 32 periodic, square and hexagonal; 32 x 32
open square), `--draws` fields with a random wavelength in 4..10 cells, direction and phase (numpy's
default_rng(`--seed`)); on a periodic sheet each plane wave is moved to the nearest wavevector the sheet admits.
Prints a markdown table: the share read as the family's kind and the median relative error of
dominant_wavelength_cells against the nearest of the field's plane waves as the sheet holds them (labyrinths:
against the band's centre).
"""

from __future__ import annotations

import argparse
import math
import sys

import numpy as np

from ..analysis import pattern2d as p2
from ..topology import Topology

__all__ = [
    "wavevector",
    "plane",
    "stripes",
    "hex_spots",
    "square_spots",
    "labyrinth",
    "dislocated",
    "SHEETS",
    "FAMILIES",
    "main",
]


def wavevector(t: Topology, lam: float, deg: float, snap: bool = False) -> tuple[float, float]:
    """Index-space (q_row, q_col) of |k| = 2 pi / lam at deg from the x axis (snap: moved to the nearest wavevector
    a periodic sheet admits, 2 pi (m / rows, m' / cols))."""
    a = math.radians(deg)
    kx, ky = 2 * math.pi / lam * math.cos(a), 2 * math.pi / lam * math.sin(a)
    q_row, q_col = ((ky * math.sqrt(3) + kx) / 2 if t.kind == "hex" else ky), kx
    if snap:
        q_row = 2 * math.pi * round(q_row * t.rows / (2 * math.pi)) / t.rows
        q_col = 2 * math.pi * round(q_col * t.cols / (2 * math.pi)) / t.cols
    return q_row, q_col


def plane(t: Topology, lam: float, deg: float, phase: float = 0.0, snap: bool = False) -> np.ndarray:
    """cos(k.x + phase) at the cells' positions, k = wavevector(t, lam, deg, snap)."""
    q_row, q_col = wavevector(t, lam, deg, snap)
    r, c = np.divmod(np.arange(t.n), t.cols)
    return np.cos(q_row * r + q_col * c + phase)


def _lam(t: Topology, lam: float, deg: float, snap: bool) -> float:
    q = wavevector(t, lam, deg, snap)
    return p2.wavelength_orientation(q, t)[0] if any(q) else math.inf


def stripes(t: Topology, lam: float, deg: float, sat: bool = False, phase: float = 0.3, snap: bool = False):
    """Stripes of amplitude 0.6 rad; sat: saturated as bistable cells are (0.6 tanh(4 u))."""
    u = 0.6 * plane(t, lam, deg, phase, snap)
    return 0.6 * np.tanh(4 * u) if sat else u


def hex_spots(t: Topology, lam: float, sat: bool = False, deg: float = 0.0, phases=(0.0, 0.0, 0.0), snap=False):
    """Three plane waves at 120 degrees (0.25 each; phases summing to 0: spots of one sign); sat: sign taken."""
    u = 0.25 * sum(plane(t, lam, deg + d, f, snap) for d, f in zip((0, 120, 240), phases))
    return 0.6 * np.sign(u) if sat else u


def square_spots(t: Topology, lam: float, sat: bool = False, deg: float = 0.0, phases=(0.0, 0.0), snap=False):
    """Two plane waves at 90 degrees (0.3 each): a checkerboard of spots; sat: sign taken."""
    u = 0.3 * sum(plane(t, lam, deg + d, f, snap) for d, f in zip((0, 90), phases))
    return 0.6 * np.sign(u) if sat else u


def labyrinth(t: Topology, lam: float, seed: int) -> np.ndarray:
    """A random field band-passed around |k| = 2 pi / lam (Gaussian of width 0.15 |k|, on the sheet's DFT grid),
    sign taken (0.6 rad)."""
    g = np.random.default_rng(seed).standard_normal(t.shape)
    qr, qc = np.meshgrid(2 * np.pi * np.fft.fftfreq(t.rows), 2 * np.pi * np.fft.fftfreq(t.cols), indexing="ij")
    qr, qc = p2._reduce(qr, qc, t.kind)
    k = np.hypot(*p2._cartesian(qr, qc, t.kind))
    k0 = 2 * math.pi / lam
    u = np.real(np.fft.ifft2(np.fft.fft2(g) * np.exp(-((k - k0) ** 2) / (2 * (0.15 * k0) ** 2)))).ravel()
    return 0.6 * np.sign(u)


def dislocated(t: Topology, cores, lam: float = 6.0, sat: bool = False) -> np.ndarray:
    """Stripes along x whose phase winds by +-2 pi around each core (x0, y0, +-1) (edge dislocations)."""
    x = t.positions()
    ph = 2 * math.pi / lam * x[:, 0] + sum(s * np.arctan2(x[:, 1] - y0, x[:, 0] - x0) for x0, y0, s in cores)
    u = 0.6 * np.cos(ph)
    return 0.6 * np.sign(u) if sat else u


SHEETS = (
    Topology((16, 16), "square"),
    Topology((16, 16), "hex"),
    Topology((32, 32), "square"),
    Topology((32, 32), "square", True),
    Topology((32, 32), "hex", True),
)


def _draw(family: str, t: Topology, rng: np.random.Generator):
    """(the kind it is, the wavelengths of its plane waves as the sheet holds them, the field)."""
    lam, deg = rng.uniform(4, 10), rng.uniform(0, 180)
    ph = rng.uniform(0, 2 * math.pi, 3)
    snap = t.periodic

    def lams(*angles):
        return [_lam(t, lam, deg + d, snap) for d in angles]

    if family == "stripes":
        return "stripes", lams(0), stripes(t, lam, deg, phase=ph[0], snap=snap)
    if family == "saturated stripes":
        return "stripes", lams(0), stripes(t, lam, deg, sat=True, phase=ph[0], snap=snap)
    if family == "hexagonal spots":
        u = hex_spots(t, lam, bool(rng.integers(2)), deg, (ph[0], ph[1], -ph[0] - ph[1]), snap)
        return "spots", lams(0, 120, 240), u
    if family == "square spots":
        return "spots", lams(0, 90), square_spots(t, lam, bool(rng.integers(2)), deg, (ph[0], ph[1]), snap)
    return "labyrinth", [lam], labyrinth(t, lam, int(rng.integers(2**31)))


FAMILIES = ("stripes", "saturated stripes", "hexagonal spots", "square spots", "labyrinth")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator.benchmarks.pattern2d", description=__doc__.split("\n")[0]
    )
    ap.add_argument("--draws", type=int, default=40, help="fields per family and sheet (default 40)")
    ap.add_argument("--seed", type=int, default=0, help="numpy default_rng seed (default 0)")
    a = ap.parse_args(argv)
    if a.draws < 1:
        print(f"--draws {a.draws}: expected a whole number >= 1", file=sys.stderr)
        return 2
    rng = np.random.default_rng(a.seed)
    print("| field | " + " | ".join(t.describe().split(" (")[0] + f" ({t.boundary})" for t in SHEETS) + " |")
    print("|---" * (len(SHEETS) + 1) + "|")
    for fam in FAMILIES:
        cells = []
        for t in SHEETS:
            hit, err = 0, []
            for _ in range(a.draws):
                want, lams, u = _draw(fam, t, rng)
                m = p2.measures(np.linspace(0, 1, 3), np.tile(u, (3, 1)), t)
                hit += m["pattern_kind"] == want
                if m["dominant_wavelength_cells"] is not None:
                    err.append(min(abs(m["dominant_wavelength_cells"] / lam - 1) for lam in lams))
            cells.append(f"{hit}/{a.draws}, {100 * float(np.median(err)):.1f} %")
        print(f"| {fam} | " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
