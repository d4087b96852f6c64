"""Linear theory of a 2-D sheet (docs/sheets.md): the dispersion relation over the wavevector, the unstable annulus,
the fastest-growing wavevectors and which modes a finite sheet allows.

The Laplacian enters the linearised lattice (analysis.stability) only through its eigenvalue q, so a plane wave
exp(i k . x + s t) on any lattice grows at the 1-D law's rate at q = L(k), the lattice's symbol
(analysis.stability.growth_rates_at_q):

    continuum   L(k) = c |k|^2        c = 1 (chain, square), 3/2 (hexagonal: the long-wave limit of its symbol)
    square      L(k) = 2 (2 - cos k_col - cos k_row)
    hexagonal   L(k) = 2 (3 - cos p1 - cos p2 - cos(p1 - p2)),  p1 = k_col, p2 = k_col / 2 + sqrt(3)/2 k_row

Wavevectors here are Cartesian, (k_row, k_col) in rad per cell spacing in the metric of Topology.positions():
k_col along a row (x), k_row down the rows (y); on the hexagonal lattice (unit bond length, rows sheared by half a
cell and spaced sqrt(3)/2) p1, p2 are the phase steps per column and per row that Topology.symbol takes. The
growth rate depends on k only through q, so the unstable set is {k : q_lo < L(k) < q_hi} for each unstable
q-interval, and the fastest-growing wavevectors are the whole contour L(k) = q*: a circle of radius sqrt(q*/c) in
the continuum, a rounded square (hexagon) on the lattice. The q-intervals are those of the 1-D continuum theory
(q = kappa^2), which analysis.stability.dispersion computes (bisected edges, refined fastest mode).
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import math
from typing import TYPE_CHECKING, Any

import numpy as np

from ..topology import Topology
from .stability import Theory, dispersion, growth_rates_at_q

if TYPE_CHECKING:
    from ..params import Params

__all__ = [
    "symbol",
    "to_phases",
    "growth_rates_2d",
    "unstable_q",
    "annulus",
    "fastest",
    "allowed_wavevectors",
    "finite_sheet",
    "theory_of_sheet",
    "zone_edge",
    "CONTINUUM_FACTOR",
    "DIRECTIONS",
]

TWO_PI = 2.0 * math.pi
SQ3 = math.sqrt(3.0)
CONTINUUM_FACTOR = {"chain": 1.0, "square": 1.0, "hex": 1.5}  # the symbol's long-wave limit: c |k|^2
# the two directions the radial extent is reported along (degrees from the k_col axis): along a bond, and the
# other high-symmetry direction (the square's diagonal; the hexagon's Gamma-M, between two bonds)
DIRECTIONS = {"square": {"axis": 0.0, "diagonal": 45.0}, "hex": {"axis": 0.0, "diagonal": 30.0}}
_RECIPROCAL = {  # reciprocal basis vectors (k_row, k_col) of the lattice, for the first Brillouin zone
    "square": np.array([[0.0, TWO_PI], [TWO_PI, 0.0]]),
    "hex": np.array([[-TWO_PI / SQ3, TWO_PI], [2 * TWO_PI / SQ3, 0.0]]),
}


def _kind(lattice: str | Topology) -> str:
    kind = lattice.kind if isinstance(lattice, Topology) else str(lattice)
    if kind not in CONTINUUM_FACTOR:
        raise ValueError(f"lattice {kind!r}: expected chain, square or hex")
    return kind


def to_phases(lattice: str | Topology, k_row, k_col) -> tuple[np.ndarray, np.ndarray]:
    """(phase step per column, phase step per row) of the Cartesian wavevector (k_row, k_col): what Topology.symbol
    takes. Square and chain: (k_col, k_row); hexagonal: (k_col, k_col / 2 + sqrt(3)/2 k_row)."""
    kr, kc = np.asarray(k_row, dtype=float), np.asarray(k_col, dtype=float)
    if _kind(lattice) == "hex":
        return kc, 0.5 * kc + 0.5 * SQ3 * kr
    return kc, kr


def symbol(lattice: str | Topology, k_row, k_col=0.0, *, discrete: bool = True) -> np.ndarray:
    """L(k) of the module docstring at the Cartesian wavevector (k_row, k_col) (numpy broadcasting). A chain takes
    its wavenumber as k_col (k_row ignored)."""
    kind = _kind(lattice)
    kr, kc = np.asarray(k_row, dtype=float), np.asarray(k_col, dtype=float)
    if kind == "chain":
        return 2.0 * (1.0 - np.cos(kc)) if discrete else kc * kc + 0.0 * kr
    if not discrete:
        return CONTINUUM_FACTOR[kind] * (kr * kr + kc * kc)
    p1, p2 = to_phases(kind, kr, kc)
    return np.asarray(Topology((3, 3), kind, True).symbol(p1, p2), dtype=float)


def _theory(theory: Theory | None) -> Theory:
    return theory or Theory("lattice", True, True, 0.0)


def growth_rates_2d(params: Params, k_row, k_col, *, theory: Theory | None = None, lattice: str | None = None):
    """Growth rates (1/s, complex, Re descending) at each wavevector, shape (*broadcast shape, 2 or 4): the 1-D law
    at q = symbol(k) (the theory's lattice or continuum symbol; lattice defaults to params.lattice)."""
    th = _theory(theory)
    kind = _kind(lattice or params.lattice)
    q = symbol(kind, k_row, k_col, discrete=th.discrete)
    s = growth_rates_at_q(params.uniform(), q.ravel(), inertia=th.inertia, motor_damping=th.motor_damping)
    return s.reshape(*q.shape, s.shape[-1])


# ---- the unstable set in q ----------------------------------------------------------------------------
def _q(lam: float | None) -> float:
    return 0.0 if lam is None else (TWO_PI / lam) ** 2


def unstable_q(params: Params, theory: Theory | None = None) -> dict:
    """The Laplacian eigenvalues q that grow, the same for every lattice: the 1-D continuum theory (q = kappa^2,
    analysis.stability.dispersion with the theory's inertia and damping) read in q.

    Returns {"intervals": [{"q": [lo, hi], "kind", "fastest_q", "fastest_growth_per_s", "period_s"}] (shortest
    waves first), "fastest_q", "fastest_growth_per_s" (the largest Re s over every q >= 0; negative when nothing
    grows), "oscillation_period_s", "regime" (analysis.stability.REGIMES), "theory" (its label)}."""
    law = dataclasses.replace(params.uniform(), cells=1, shape=(), lattice="chain", boundary="open")  # q only
    return copy.deepcopy(_unstable_q(law, _theory(theory)))


@functools.lru_cache(maxsize=64)
def _unstable_q(params: Params, th: Theory) -> dict:
    d = dispersion(
        params, theory=Theory(th.model, th.inertia, False, th.motor_damping), n_kappa=4000
    )  # continuum: q = kappa^2
    ivs = []
    for iv in d["unstable_intervals"]:
        lo_l, hi_l = iv["lambda_cells"]
        ivs.append(
            {
                "q": [_q(hi_l), _q(lo_l)],
                "kind": iv["kind"],
                "fastest_q": _q(iv["fastest_lambda_cells"]),
                "fastest_growth_per_s": iv["fastest_growth_per_s"],
                "period_s": iv["period_s"],
            }
        )
    return {
        "intervals": ivs,
        "fastest_q": float(d["fastest_kappa"]) ** 2,
        "fastest_growth_per_s": d["fastest_growth_per_s"],
        "oscillation_period_s": d["oscillation_period_s"],
        "regime": d["regime"],
        "theory": th.label(),
    }


# ---- radial extent along a direction ---------------------------------------------------------------------
def _unit(deg: float) -> np.ndarray:
    """(k_row, k_col) unit vector at `deg` degrees from the k_col axis."""
    return np.array([math.sin(math.radians(deg)), math.cos(math.radians(deg))])


def zone_edge(lattice: str, deg: float) -> float:
    """|k| where the ray at `deg` degrees leaves the first Brillouin zone (the Wigner-Seitz cell of _RECIPROCAL)."""
    u = _unit(deg)
    b = _RECIPROCAL[lattice]
    best = math.inf
    for m1 in range(-2, 3):
        for m2 in range(-2, 3):
            g = m1 * b[0] + m2 * b[1]
            ug = float(u @ g)
            if ug > 1e-12:
                best = min(best, float(g @ g) / (2.0 * ug))
    return best


def _radius(lattice: str, deg: float, q: float) -> float | None:
    """|k| along the ray at `deg` where the lattice symbol equals q (it grows monotonically from 0 at the centre
    to the zone edge); None when q exceeds the symbol's value at the zone edge."""
    u = _unit(deg)
    edge = zone_edge(lattice, deg)

    def f(t: float) -> float:
        return float(symbol(lattice, t * u[0], t * u[1])) - q

    if f(edge) < 0:
        return None
    if q <= 0:
        return 0.0
    lo, hi = 0.0, edge
    for _ in range(200):
        mid = 0.5 * (lo + hi)
        if mid in (lo, hi):
            break
        if f(mid) < 0:
            lo = mid
        else:
            hi = mid
    return 0.5 * (lo + hi)


def _lam(k: float | None) -> float | None:
    return None if k is None or k <= 0 else TWO_PI / k


def _extent(lattice: str, deg: float, q_lo: float, q_hi: float) -> dict:
    inner = _radius(lattice, deg, q_lo)
    outer = _radius(lattice, deg, q_hi)
    edge = zone_edge(lattice, deg)
    if inner is None:  # the band lies beyond the zone along this ray: nothing grows in this direction
        return {"k": None, "lambda_cells": None, "to_zone_edge": False}
    k_out = edge if outer is None else outer
    return {"k": [inner, k_out], "lambda_cells": [_lam(k_out), _lam(inner)], "to_zone_edge": outer is None}


def annulus(params: Params, theory: Theory | None = None, lattice: str | None = None) -> dict:
    """The unstable set of the sheet in wavevector space, per unstable q-interval (unstable_q):

    continuum: an annulus |k| in [k_in, k_out] (k_in 0: a disc, the longest waves grow), radii
        sqrt(q / c), wavelengths 2 pi / |k| (cells, the positions' metric);
    discrete: the set {k : q_lo < L(k) < q_hi} in the Brillouin zone, its radial extent along a bond ("axis") and
        along the other high-symmetry direction ("diagonal": 45 degrees square, 30 degrees hexagonal), with
        to_zone_edge when it reaches the zone's edge there (k None: nothing grows along that ray).
    Keys: lattice, theory, regime, intervals [{"kind", "q", "continuum": {"k", "lambda_cells"}, "discrete":
    {"axis": ..., "diagonal": ...}}], and "k"/"lambda_cells" of the first (shortest-wave) interval for the
    theory's own symbol (continuum radii, or the lattice's along the axis) for a one-line reading."""
    th = _theory(theory)
    kind = _kind(lattice or params.lattice)
    if kind == "chain":
        raise ValueError("annulus: a chain has no annulus; use analysis.stability.dispersion")
    uq = unstable_q(params, th)
    c = CONTINUUM_FACTOR[kind]
    out_iv = []
    for iv in uq["intervals"]:
        lo, hi = iv["q"]
        kin, kout = math.sqrt(lo / c), math.sqrt(hi / c)
        out_iv.append(
            {
                "kind": iv["kind"],
                "q": [lo, hi],
                "continuum": {"k": [kin, kout], "lambda_cells": [_lam(kout), _lam(kin)]},
                "discrete": {name: _extent(kind, deg, lo, hi) for name, deg in DIRECTIONS[kind].items()},
            }
        )
    first = out_iv[0] if out_iv else None
    if first is None:
        k = lam = None
    elif th.discrete:
        k, lam = first["discrete"]["axis"]["k"], first["discrete"]["axis"]["lambda_cells"]
    else:
        k, lam = first["continuum"]["k"], first["continuum"]["lambda_cells"]
    return {
        "lattice": kind,
        "theory": uq["theory"],
        "regime": uq["regime"],
        "intervals": out_iv,
        "k": k,
        "lambda_cells": lam,
    }


def fastest(params: Params, theory: Theory | None = None, lattice: str | None = None) -> dict:
    """The fastest-growing wavevectors: the contour L(k) = q* (q* the fastest q of unstable_q).

    continuum: |k| = sqrt(q*/c) in every direction; discrete: |k| along the axis and the diagonal (None along a ray
    whose zone edge has L < q*: then the fastest mode is the zone corner, "corner": true). lambda_cells /
    k: the theory's own reading (continuum, or the lattice along the axis); None: the uniform mode is fastest."""
    th = _theory(theory)
    kind = _kind(lattice or params.lattice)
    uq = unstable_q(params, th)
    qs = uq["fastest_q"]
    c = CONTINUUM_FACTOR[kind]
    kc = math.sqrt(qs / c)
    disc: dict[str, Any] = {}
    if kind != "chain":
        for name, deg in DIRECTIONS[kind].items():
            r = _radius(kind, deg, qs)
            disc[name] = {"k": r, "lambda_cells": _lam(r)}
        qmax = 8.0 if kind == "square" else 9.0
        disc["corner"] = qs >= qmax
    k_own = kc if not th.discrete or kind == "chain" else disc["axis"]["k"]
    if th.discrete and kind == "chain":
        k_own = math.acos(max(-1.0, 1.0 - qs / 2.0))
    return {
        "lattice": kind,
        "theory": uq["theory"],
        "q": qs,
        "growth_per_s": uq["fastest_growth_per_s"],
        "period_s": uq["oscillation_period_s"],
        "continuum": {"k": kc, "lambda_cells": _lam(kc)},
        "discrete": disc,
        "k": k_own,
        "lambda_cells": _lam(k_own),
    }


# ---- a finite sheet ----------------------------------------------------------------------------------------
def _cartesian(kind: str, p_row, p_col) -> tuple[np.ndarray, np.ndarray]:
    """(k_row, k_col) of the phase steps per row and per column (the inverse of to_phases)."""
    p_row, p_col = np.asarray(p_row, dtype=float), np.asarray(p_col, dtype=float)
    if kind == "hex":
        return (p_row - 0.5 * p_col) * 2.0 / SQ3, p_col
    return p_row, p_col


def _reduce(kind: str, kr: float, kc: float) -> tuple[float, float]:
    """The shortest wavevector equivalent to (k_row, k_col) modulo the reciprocal lattice (the one whose
    wavelength the lattice shows)."""
    if kind not in _RECIPROCAL:
        return kr, kc
    b = _RECIPROCAL[kind]
    best = (kr, kc)
    for m1 in (-1, 0, 1):
        for m2 in (-1, 0, 1):
            g = m1 * b[0] + m2 * b[1]
            cand = (kr - float(g[0]), kc - float(g[1]))
            if math.hypot(*cand) < math.hypot(*best) - 1e-12:
                best = cand
    return best


def _wrap(p: np.ndarray) -> np.ndarray:
    """Phases into (-pi, pi]."""
    return np.pi - np.mod(np.pi - p, TWO_PI)


def allowed_wavevectors(topology: Topology) -> list[dict]:
    """The Laplacian eigenmodes of a finite lattice, one dict per mode: m (the mode's indices, (m_row, m_col)),
    k ([k_row, k_col] Cartesian rad/cell, None where the modes are not plane waves), q (the Laplacian eigenvalue)
    and lambda_cells (2 pi / |k|; None for the uniform mode).

    periodic: plane waves exp(i k . x), phase steps 2 pi m / N per axis (m in -N/2..N/2, both of a +-k pair
        listed; q = the symbol). open chain or square sheet: the Neumann cosines cos(pi m (j - 1/2) / N),
        m = 0..N-1 per axis, k = pi m / N (q = the symbol there). open hexagonal sheet: its edges do not separate,
        so the modes are the eigenvectors of Topology.laplacian() (q its eigenvalues, k None, lambda_cells the
        continuum-equivalent 2 pi / sqrt(q / c))."""
    kind = topology.kind
    rows, cols = topology.rows, topology.cols
    out: list[dict] = []
    if kind == "hex" and not topology.periodic:
        eig = np.linalg.eigvalsh(topology.laplacian().toarray())
        for j, qj in enumerate(np.sort(np.clip(eig, 0.0, None))):
            k_eq = math.sqrt(qj / CONTINUUM_FACTOR["hex"])
            out.append({"m": (j,), "k": None, "q": float(qj), "lambda_cells": _lam(k_eq) if j else None})
        return out
    if topology.periodic:
        mr = np.fft.fftfreq(rows, 1.0 / rows).astype(int) if kind != "chain" else np.array([0])
        mc = np.fft.fftfreq(cols, 1.0 / cols).astype(int)
        pr, pc = _wrap(TWO_PI * mr / rows), _wrap(TWO_PI * mc / cols)
    else:
        mr = np.arange(rows) if kind != "chain" else np.array([0])
        mc = np.arange(cols)
        pr, pc = np.pi * mr / rows, np.pi * mc / cols
    for a, p_r in zip(mr, pr):
        for b, p_c in zip(mc, pc):
            cr, cc = _cartesian(kind, p_r, p_c)
            k_r, k_c = _reduce(kind, float(cr), float(cc))
            q = float(symbol(kind, k_r, k_c))
            out.append({"m": (int(a), int(b)), "k": [k_r, k_c], "q": q, "lambda_cells": _lam(math.hypot(k_r, k_c))})
    return out


def finite_sheet(params: Params, theory: Theory | None = None, topology: Topology | None = None) -> dict:
    """Which of a finite sheet's modes grow (allowed_wavevectors with the growth rate at their q; a continuum
    theory takes the continuum's symbol at the same wavevectors), fastest first,
    and how the fastest allowed mode compares with the unbounded lattice's fastest wavelength.

    Returns {"topology", "modes" (each with growth_per_s, imag_per_s, unstable), "unstable" (the growing modes'
    count), "fastest_mode" (the allowed mode of largest Re s), "fastest_lambda_cells" (the lattice's, along
    the axis; the continuum's for a continuum theory), "relative_to_fastest" (the fastest allowed mode's
    wavelength over that, minus 1; None when either is the uniform mode), "in_annulus" (the fastest allowed mode
    grows: it lies inside the unstable set)}."""
    th = _theory(theory)
    topo = topology or params.topology
    modes = allowed_wavevectors(topo)
    if not th.discrete:  # the continuum's symbol at the same wavevectors (an open hexagonal sheet keeps its q)
        for m in modes:
            if m["k"] is not None:
                m["q"] = float(symbol(topo.kind, m["k"][0], m["k"][1], discrete=False))
    s = growth_rates_at_q(
        params.uniform(), [m["q"] for m in modes], inertia=th.inertia, motor_damping=th.motor_damping
    )[:, 0]
    for m, sm in zip(modes, s):
        m["growth_per_s"] = float(sm.real)
        m["imag_per_s"] = float(abs(sm.imag))
        m["unstable"] = bool(sm.real > 0)
    modes.sort(key=lambda m: -m["growth_per_s"])
    top = modes[0]
    fast = fastest(params, th, topo.kind)
    lam_best = fast["lambda_cells"]
    rel = None if top["lambda_cells"] is None or lam_best is None else top["lambda_cells"] / lam_best - 1.0
    return {
        "topology": topo.describe(),
        "theory": fast["theory"],
        "modes": modes,
        "unstable": sum(m["unstable"] for m in modes),
        "fastest_mode": top,
        "fastest_lambda_cells": lam_best,
        "relative_to_fastest": rel,
        "in_annulus": top["unstable"],
    }


def theory_of_sheet(params: Params, theory: Theory | None = None) -> dict:
    """What analysis.summary may put beside a sheet's run: the annulus, the fastest wavelength and the finite
    sheet's fastest allowed mode, in a few JSON-ready keys (regime, theory, unstable_lambda_cells [lo, hi] of the
    first interval, fastest_lambda_cells, fastest_growth_per_s, oscillation_period_s, sheet_fastest_lambda_cells,
    sheet_fastest_growth_per_s, sheet_unstable_modes)."""
    th = _theory(theory)
    an = annulus(params, th)
    fa = fastest(params, th)
    fs = finite_sheet(params, th)
    top = fs["fastest_mode"]
    return {
        "regime": an["regime"],
        "theory": f"{an['theory']} ({'lattice symbol' if th.discrete else 'continuum symbol'}, {an['lattice']})",
        "unstable_lambda_cells": an["lambda_cells"],
        "fastest_lambda_cells": fa["lambda_cells"],
        "fastest_growth_per_s": fa["growth_per_s"],
        "oscillation_period_s": fa["period_s"],
        "sheet_fastest_lambda_cells": top["lambda_cells"],
        "sheet_fastest_wavevector": top["k"],
        "sheet_fastest_growth_per_s": top["growth_per_s"],
        "sheet_unstable_modes": fs["unstable"],
    }
