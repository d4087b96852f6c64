"""2-D pattern measures of a sheet (docs/patterns2d.md#definitions): wavelength, orientation, kind, boundary, defects.

Every measure reads one frame of alpha on a sheet (`host_emulator.topology.Topology`, square or hexagonal, open or
periodic); `measures(t, alpha, topology)` picks the frame and returns them all. Definitions (the docs' section
gives the reasoning and the limits):

* frame: the final alpha; for an oscillation, the frame of the final window with the largest spatial variance.
* structure factor S(q): |DFT|^2 of the frame on its (rows, cols) grid, q = (q_row, q_col) in rad/cell conjugate to
  the (row, col) indices. A periodic sheet: the plain DFT (the wavevectors it admits, 2 pi (m/rows, m'/cols)). An
  open sheet: mean (window-weighted) removed, a Hann window, zero-padded to max(64, 4 x) points per axis. Cartesian
  k = (kx, ky) follows `Topology.positions()` (x along a row, y down the rows; a hexagonal sheet's rows are sheared
  half a cell and spaced sqrt(3)/2, and each q is taken as its alias of smallest |k|).
* dominant wavevector q*: the largest S(q) with |k| >= pi / max(rows, cols) (wavelengths up to twice the sheet),
  ties to the smaller |k|; on an open sheet refined by least squares (the plane wave A cos(q.x) + B sin(q.x) + C
  explaining most of the frame's variance, as observables.spatial_period does on a chain; to 1e-6 rad/cell).
  dominant_wavelength_cells = 2 pi / |k*|, orientation_deg = direction of k* from the x axis towards y, in
  [0, 180) (the wavevector's direction: stripes along y have orientation 0).
* sign field: sign(alpha) on the cells with |alpha| > threshold (observables.WALL_THRESHOLD_RAD); a cell at or
  below it takes the sign of the nearest such cell (bond steps; ties to the larger |alpha|, then the lower cell).
  boundary_length_cells: bonds whose two cells' signs differ (on a 1 x N sheet: observables.domain_walls).
* pattern_kind: "oscillation" when the motion lasts to the end (observables.is_steady false and
  observables.temporal_period found in the final window); else "rest" when no cell exceeds the threshold or the
  frame is flat within it; else "stripes" when ring_order[2] >= STRIPE_ORDER_MIN (one direction holds the power
  on the ring 0.7..1.3 |k*| of S: one pair of peaks); else "spots" when max(ring_order[4], ring_order[6]) >=
  SPOT_ORDER_MIN (two pairs at 90 degrees, three at 60) with evidence of spots (the sheet spans more than one
  wavelength along x and along y, or the frame has a compact sign domain: one that neither touches an open edge
  nor wraps around a periodic sheet), or when compact_density >= SPOT_COMPACT_MIN (many compact domains); else
  "labyrinth" (power spread round the ring, domains that meander; also a frame with neither, such as a band on a
  sheet smaller than one wavelength, whose few domains all touch its edges). ring_order[m] = |<exp(i m theta)>|_S
  on the ring, divided by the same for a plane wave at q* through the same window (so a small open sheet's broad
  peaks still give 1).
* defects: dislocations, the zeros of the demodulated field z = the frame band-passed around +k* (a Gaussian of
  width |k*| / 2 in k; one-sided, so z ~ A exp(i phase) of the stripes): the plaquettes (square: 2 x 2 cells,
  hexagonal: triangles) around which arg z turns by a nonzero multiple of 2 pi. Straight stripes and perfect
  spot lattices have none; a stripe that ends inside the sheet (an edge dislocation) is one.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.optimize import minimize

from ..topology import Topology
from .observables import DEFAULT_TOL_RAD, WALL_THRESHOLD_RAD, _window, is_steady, temporal_period

__all__ = [
    "KINDS",
    "STRIPE_ORDER_MIN",
    "SPOT_ORDER_MIN",
    "SPOT_COMPACT_MIN",
    "measures",
    "analysed_frame",
    "structure_factor",
    "dominant_wavevector",
    "wavelength_orientation",
    "sign_field",
    "boundary_length",
    "ring_order",
    "domains",
    "compact_density",
    "classify",
    "defects",
]

KINDS = ("stripes", "spots", "labyrinth", "rest", "oscillation")
STRIPE_ORDER_MIN = 0.8  # ring_order[2] at or above which the pattern is stripes
SPOT_ORDER_MIN = 0.7  # max(ring_order[4], ring_order[6]) at or above which a pattern that is not stripes is spots
SPOT_COMPACT_MIN = 0.4  # compact_density at or above which a pattern that is not stripes is spots
_SQ3 = math.sqrt(3.0)


def _check(topology: Topology, field: np.ndarray) -> np.ndarray:
    if not topology.is_sheet:
        raise ValueError(f"pattern2d measures sheets; got a {topology.describe()}")
    u = np.asarray(field, dtype=float)
    if u.shape != (topology.n,):
        raise ValueError(f"a frame of {topology.n} cells expected, got shape {u.shape}")
    if not np.all(np.isfinite(u)):
        raise ValueError("non-finite values in alpha (a diverged run?)")
    return u


# ---- wavevectors -----------------------------------------------------------------------------------------------
def _cartesian(q_row, q_col, kind: str):
    """(kx, ky) of index-space wavevectors (phase q_row * row + q_col * col)."""
    q_row, q_col = np.asarray(q_row, dtype=float), np.asarray(q_col, dtype=float)
    if kind == "hex":
        return q_col, (2.0 * q_row - q_col) / _SQ3
    return q_col, q_row


def _reduce(q_row, q_col, kind: str):
    """Each index-space q as its alias q + 2 pi m of smallest Cartesian |k| (the same q on the lattice)."""
    q_row, q_col = np.asarray(q_row, dtype=float), np.asarray(q_col, dtype=float)
    q_row = (q_row + math.pi) % (2 * math.pi) - math.pi
    q_col = (q_col + math.pi) % (2 * math.pi) - math.pi
    if kind != "hex":
        return q_row, q_col
    best_r, best_c = q_row.copy(), q_col.copy()
    best = np.hypot(*_cartesian(q_row, q_col, kind))
    for mr in (-1, 0, 1):
        for mc in (-1, 0, 1):
            r, c = q_row + 2 * math.pi * mr, q_col + 2 * math.pi * mc
            d = np.hypot(*_cartesian(r, c, kind))
            better = d < best - 1e-12
            best_r, best_c, best = np.where(better, r, best_r), np.where(better, c, best_c), np.minimum(d, best)
    return best_r, best_c


@dataclass(frozen=True)
class Spectrum:
    """The structure factor S on an index-space grid q_row x q_col (2-D arrays) with Cartesian kx, ky, |k|."""

    S: np.ndarray
    q_row: np.ndarray
    q_col: np.ndarray
    kx: np.ndarray
    ky: np.ndarray
    k: np.ndarray


def _padded(n: int) -> int:
    return 1 if n == 1 else max(64, 4 * n)


def _hann(n: int) -> np.ndarray:
    return np.hanning(n + 2)[1:-1] if n > 1 else np.ones(1)


def structure_factor(field: np.ndarray, topology: Topology) -> Spectrum:
    """S(q) of one frame (module docstring): the plain DFT on a periodic sheet, windowed and zero-padded on an
    open one."""
    g = topology.grid(_check(topology, field))
    rows, cols = g.shape
    if topology.periodic:
        w, shape = np.ones_like(g), (rows, cols)
    else:
        w, shape = np.outer(_hann(rows), _hann(cols)), (_padded(rows), _padded(cols))
    h = (g - (w * g).sum() / w.sum()) * w
    S = np.abs(np.fft.fft2(h, s=shape)) ** 2
    qr, qc = np.meshgrid(2 * np.pi * np.fft.fftfreq(shape[0]), 2 * np.pi * np.fft.fftfreq(shape[1]), indexing="ij")
    qr, qc = _reduce(qr, qc, topology.kind)
    kx, ky = _cartesian(qr, qc, topology.kind)
    return Spectrum(S, qr, qc, kx, ky, np.hypot(kx, ky))


def _explained(u: np.ndarray, rc: np.ndarray, q: np.ndarray) -> float:
    """Share of u's variance (u mean-free) fitted by [cos(q.rc), sin(q.rc), 1]."""
    ph = rc @ q
    basis = np.column_stack([np.cos(ph), np.sin(ph), np.ones_like(ph)])
    coef, *_ = np.linalg.lstsq(basis, u, rcond=None)
    r = u - basis @ coef
    return float(1.0 - (r @ r) / (u @ u))


def _index_coords(topology: Topology) -> np.ndarray:
    r, c = np.divmod(np.arange(topology.n), topology.cols)
    return np.column_stack([r, c]).astype(float)


def dominant_wavevector(field: np.ndarray, topology: Topology, spectrum: Spectrum | None = None):
    """q* = (q_row, q_col) in rad/cell, or None for a flat frame (module docstring)."""
    u = _check(topology, field)
    if np.ptp(u) == 0:
        return None
    sp = spectrum or structure_factor(u, topology)
    k_min = math.pi / max(topology.rows, topology.cols) - 1e-12
    ok = sp.k >= k_min
    if not ok.any():
        return None
    s = sp.S[ok] / sp.S[ok].max()
    level = np.round(s * 1e9)  # equal powers (to 1e-9) tie, broken by the smaller |k|, then the angle
    ang = np.mod(np.arctan2(sp.ky[ok], sp.kx[ok]), np.pi)
    i = np.lexsort((ang, sp.k[ok], -level))[0]
    q = np.array([sp.q_row[ok][i], sp.q_col[ok][i]])
    if not topology.periodic:
        rc = _index_coords(topology)
        um = u - u.mean()
        e0 = _explained(um, rc, q)
        step = 2 * math.pi / max(_padded(topology.rows), _padded(topology.cols))
        simplex = np.array([q, q + [step, 0.0], q + [0.0, step]])
        r = minimize(
            lambda x: -_explained(um, rc, x),
            q,
            method="Nelder-Mead",
            options={"initial_simplex": simplex, "xatol": 1e-6, "fatol": 1e-10},
        )
        if -r.fun > e0 and np.all(np.abs(r.x - q) < 4 * step):
            q = np.round(np.asarray(r.x, dtype=float), 6)  # to 1e-6 rad/cell: the optimiser's own resolution
    qr, qc = _reduce(q[0], q[1], topology.kind)
    kx, ky = _cartesian(qr, qc, topology.kind)
    theta = math.atan2(float(ky), float(kx))
    if theta < 0 or theta >= math.pi:  # k and -k are the same pattern: keep the one in [0, 180) degrees
        qr, qc = _reduce(-qr, -qc, topology.kind)
    return float(qr), float(qc)


def wavelength_orientation(q, topology: Topology) -> tuple[float, float]:
    """(2 pi / |k| in cells, direction of k in degrees in [0, 180)) of an index-space wavevector q."""
    kx, ky = _cartesian(q[0], q[1], topology.kind)
    kx, ky = float(kx), float(ky)
    deg = math.degrees(math.atan2(ky, kx)) % 180.0
    return 2 * math.pi / math.hypot(kx, ky), (0.0 if deg >= 180.0 else deg)


# ---- the sign field and its domains --------------------------------------------------------------------------------
def sign_field(field: np.ndarray, topology: Topology, threshold_rad: float = WALL_THRESHOLD_RAD) -> np.ndarray:
    """(n,) int8 in {-1, +1} (module docstring); all zeros when no cell exceeds the threshold."""
    u = _check(topology, field)
    if not (math.isfinite(threshold_rad) and threshold_rad >= 0):
        raise ValueError(f"threshold_rad={threshold_rad!r} must be finite and >= 0")
    above = np.abs(u) > threshold_rad
    sig = np.zeros(topology.n, dtype=np.int8)
    if not above.any():
        return sig
    sig[above] = np.sign(u[above]).astype(np.int8)
    key = np.where(above, np.abs(u), -1.0)  # the |alpha| of each cell's source cell
    src = np.where(above, np.arange(topology.n), -1)
    done = above.copy()
    b = np.asarray(topology.bonds)
    a_, b_ = np.concatenate([b[:, 0], b[:, 1]]), np.concatenate([b[:, 1], b[:, 0]])  # both directions
    while not done.all():
        m = done[a_] & ~done[b_]
        if not m.any():  # cells out of reach of any source (a sheet in pieces cannot happen; kept safe)
            break
        frm, to = a_[m], b_[m]
        order = np.lexsort((src[frm], -key[frm], to))
        to_s, first = np.unique(to[order], return_index=True)
        pick = frm[order][first]
        sig[to_s], key[to_s], src[to_s] = sig[pick], key[pick], src[pick]
        done[to_s] = True
    return sig


def boundary_length(field: np.ndarray, topology: Topology, threshold_rad: float = WALL_THRESHOLD_RAD) -> int:
    """The number of bonds across which the sign field changes."""
    s = sign_field(field, topology, threshold_rad)
    b = topology.bonds
    return int(np.count_nonzero(s[b[:, 0]] != s[b[:, 1]]))


def _plaquettes(topology: Topology) -> np.ndarray:
    """(m, 3 or 4) 0-based cells of each elementary loop, in order around it: square 2 x 2 blocks, hexagonal
    triangles; only loops whose cells all exist (wrapping on a periodic sheet)."""
    rows, cols = topology.shape
    loops = (
        [((0, 0), (0, 1), (1, 1), (1, 0))]
        if topology.kind == "square"
        else [((0, 0), (0, 1), (1, 0)), ((0, 0), (1, 0), (1, -1))]
    )
    r, c = np.divmod(np.arange(topology.n), cols)
    out = []
    for loop in loops:
        rr = np.stack([r + dr for dr, _ in loop], axis=1)
        cc = np.stack([c + dc for _, dc in loop], axis=1)
        if topology.periodic:
            rr, cc = rr % rows, cc % cols
        else:
            ok = ((rr >= 0) & (rr < rows) & (cc >= 0) & (cc < cols)).all(axis=1)
            rr, cc = rr[ok], cc[ok]
        out.append(rr * cols + cc)
    return np.concatenate(out).astype(np.int64)


_STEP = {0: (0, 1), 1: (1, 0), 2: (1, -1)}  # bond_axis -> (d_row, d_col) from a bond's first cell to its second


def domains(sign: np.ndarray, topology: Topology) -> tuple[np.ndarray, np.ndarray]:
    """(labels (n,) of the connected domains of equal sign (bonds within a sign), compact (ndomain,) bool): a
    domain is compact when it neither touches an open sheet's edge nor wraps around a periodic sheet."""
    from scipy.sparse import coo_matrix
    from scipy.sparse.csgraph import connected_components

    s = np.asarray(sign)
    b = np.asarray(topology.bonds)
    same = s[b[:, 0]] == s[b[:, 1]]
    m = coo_matrix((np.ones(int(same.sum())), (b[same, 0], b[same, 1])), (topology.n,) * 2)
    nd, lab = connected_components(m, directed=False)
    compact = np.ones(nd, dtype=bool)
    rows, cols = topology.shape
    if not topology.periodic:
        r, c = np.divmod(np.arange(topology.n), cols)
        compact[np.unique(lab[(r == 0) | (r == rows - 1) | (c == 0) | (c == cols - 1)])] = False
        return lab, compact
    # periodic: walk each domain keeping unwrapped (row, col); meeting a cell again elsewhere means it wraps
    adj: list[list[tuple[int, int, int]]] = [[] for _ in range(topology.n)]
    for (i, j), a in zip(b[same].tolist(), np.asarray(topology.bond_axis)[same].tolist()):
        dr, dc = _STEP[a]
        adj[i].append((j, dr, dc))
        adj[j].append((i, -dr, -dc))
    pos: dict[int, tuple[int, int]] = {}
    for start in range(topology.n):
        if start in pos:
            continue
        pos[start] = (0, 0)
        stack = [start]
        while stack:
            i = stack.pop()
            pr, pc = pos[i]
            for j, dr, dc in adj[i]:
                q = (pr + dr, pc + dc)
                if j not in pos:
                    pos[j] = q
                    stack.append(j)
                elif pos[j] != q:
                    compact[lab[j]] = False
    return lab, compact


def compact_density(sign: np.ndarray, topology: Topology, wavelength: float) -> float:
    """The number of compact domains (both signs) per lambda^2 of sheet (area: cells, sqrt(3)/2 each on a
    hexagonal sheet): about 0.9 for hexagonal spots (one per spot), 0 for stripes, small for a labyrinth."""
    area = topology.n * (_SQ3 / 2 if topology.kind == "hex" else 1.0)
    return int(domains(sign, topology)[1].sum()) * wavelength**2 / area


def ring_order(field: np.ndarray, topology: Topology, q, spectrum: Spectrum | None = None) -> dict[int, float]:
    """{m: |<exp(i m theta)>|_S on the ring 0.7..1.3 |k*|, over the same of a plane wave at q} for m = 2, 4, 6:
    1 for m = 2 when one direction holds the ring's power (stripes), for m = 4 when two at 90 degrees do (square
    spots; stripes too), for m = 6 when three at 60 degrees do (hexagonal spots; stripes too); lower for a ring."""
    q = np.asarray(q, dtype=float)
    k0 = float(np.hypot(*_cartesian(q[0], q[1], topology.kind)))

    def order(sp: Spectrum) -> dict[int, float]:
        ring = (sp.k >= 0.7 * k0) & (sp.k <= 1.3 * k0)
        w, th = sp.S[ring], np.arctan2(sp.ky[ring], sp.kx[ring])
        tot = w.sum()
        return {m: float(abs((w * np.exp(1j * m * th)).sum()) / tot) if tot > 0 else 0.0 for m in (2, 4, 6)}

    u = _check(topology, field)
    got = order(spectrum or structure_factor(u, topology))
    ref = order(structure_factor(np.cos(_index_coords(topology) @ q), topology))
    return {m: got[m] / ref[m] if ref[m] > 0 else 0.0 for m in got}


def classify(field: np.ndarray, topology: Topology, threshold_rad: float = WALL_THRESHOLD_RAD) -> str:
    """ "rest", "stripes", "spots" or "labyrinth" of one frame (module docstring; "oscillation" needs the run)."""
    return _frame(_check(topology, field), topology, threshold_rad)[0]


def _frame(u: np.ndarray, topology: Topology, threshold_rad: float):
    """(kind, q*) of one checked frame; q* None at rest."""
    if np.abs(u).max() <= threshold_rad or np.ptp(u) <= threshold_rad:
        return "rest", None
    sp = structure_factor(u, topology)
    q = dominant_wavevector(u, topology, sp)
    if q is None:
        return "rest", None
    order = ring_order(u, topology, q, sp)
    if order[2] >= STRIPE_ORDER_MIN:
        return "stripes", q
    lam, _ = wavelength_orientation(q, topology)
    dens = compact_density(sign_field(u, topology, threshold_rad), topology, lam)
    # the n-fold order counts only with evidence of spots: a compact domain, or a sheet that spans more than one
    # wavelength both ways (one smaller than a wavelength, whose few domains all touch its edges, has a ring too
    # broad to tell spots from one curved band; square spots' domains join at saddles, so the size must do there)
    height = topology.rows * (_SQ3 / 2 if topology.kind == "hex" else 1.0)
    holds = min(topology.cols, height) > lam
    if max(order[4], order[6]) >= SPOT_ORDER_MIN and (holds or dens > 0):
        return "spots", q
    if dens >= SPOT_COMPACT_MIN:
        return "spots", q
    return "labyrinth", q


# ---- defects ---------------------------------------------------------------------------------------------------
def defects(field: np.ndarray, topology: Topology, q) -> int:
    """Dislocations: plaquettes around which the phase of the demodulated field winds (module docstring)."""
    g = topology.grid(_check(topology, field))
    rows, cols = g.shape
    shape = (rows, cols) if topology.periodic else (2 * rows, 2 * cols)
    F = np.fft.fft2(g - g.mean(), s=shape)
    qr, qc = np.meshgrid(2 * np.pi * np.fft.fftfreq(shape[0]), 2 * np.pi * np.fft.fftfreq(shape[1]), indexing="ij")
    qr, qc = _reduce(qr, qc, topology.kind)
    kx, ky = _cartesian(qr, qc, topology.kind)
    kx0, ky0 = _cartesian(q[0], q[1], topology.kind)
    k0 = math.hypot(float(kx0), float(ky0))
    h = np.exp(-((kx - kx0) ** 2 + (ky - ky0) ** 2) / (2 * (0.5 * k0) ** 2))
    z = np.fft.ifft2(F * h)[:rows, :cols].ravel()
    p = _plaquettes(topology)
    zz = z[p]
    turn = np.angle(np.roll(zz, -1, axis=1) / np.where(zz == 0, 1e-300, zz)).sum(axis=1)
    return int(np.count_nonzero(np.round(turn / (2 * np.pi))))


# ---- a run -----------------------------------------------------------------------------------------------------
def analysed_frame(
    t: np.ndarray, alpha: np.ndarray, *, settle_window_s: float | None = None, tol_rad: float = DEFAULT_TOL_RAD
) -> tuple[np.ndarray, bool]:
    """(the frame the measures read, whether the run oscillates): the final frame, or for an oscillation (not
    steady, and a temporal period whose last crossing lies in the final window) the frame of the final window with
    the largest spatial variance."""
    t = np.asarray(t, dtype=float)
    a = np.asarray(alpha, dtype=float)
    if a.ndim != 2 or t.ndim != 1 or a.shape[0] != t.size or t.size < 2:
        raise ValueError(f"shape mismatch: t {t.shape}, alpha {a.shape}; expected alpha (T, n) with T = len(t) >= 2")
    osc = not is_steady(t, a, a, settle_window_s=settle_window_s, tol_rad=tol_rad) and (
        temporal_period(t, a, settle_window_s=settle_window_s, tol_rad=tol_rad, until_the_end=True) is not None
    )
    if not osc:
        return a[-1], False
    idx = _window(t, settle_window_s)
    return a[idx[int(np.argmax(a[idx].var(axis=1)))]], True


def measures(
    t: np.ndarray,
    alpha: np.ndarray,
    topology: Topology,
    *,
    threshold_rad: float = WALL_THRESHOLD_RAD,
    settle_window_s: float | None = None,
    tol_rad: float = DEFAULT_TOL_RAD,
) -> dict:
    """The pattern measures of a run on a sheet (alpha (samples, n) in cell order) as a JSON-ready dict."""
    frame, osc = analysed_frame(t, alpha, settle_window_s=settle_window_s, tol_rad=tol_rad)
    u = _check(topology, frame)
    kind, q = _frame(u, topology, threshold_rad)
    if osc:
        kind = "oscillation"
    lam, deg = wavelength_orientation(q, topology) if q is not None else (None, None)
    return {
        "dominant_wavelength_cells": lam,
        "dominant_wavevector": None if q is None else [q[0], q[1]],
        "orientation_deg": deg,
        "pattern_kind": kind,
        "boundary_length_cells": 0 if q is None else boundary_length(u, topology, threshold_rad),
        "defects": 0 if q is None else defects(u, topology, q),
    }
