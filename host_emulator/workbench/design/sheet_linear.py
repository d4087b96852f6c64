"""Step 1 on a sheet, the first guess: each region's law from the square lattice's linear theory (the pattern law
grows, at the target's wavelength if it names one; the rest law decays at every wavevector and holds the pattern's
edge off its cells), then the whole sheet's eigenproblem as the check that its fastest mode lives in the pattern
region."""

from __future__ import annotations

import math

import numpy as np

from ...analysis.sheet_modes import sheet_modes
from ...analysis.stability import Theory, growth_rates_at_q, theory_of
from ...params import Params
from .constants import MIN_GROWTH_PER_S
from .linear import evolve_score
from .sheet_landing import LAMBDA_TOL
from .sheet_target import SheetTarget
from .space import Space, _shape_ok

Q_MAX = 8.0  # the square lattice's symbol 2 (2 - cos k_row - cos k_col) lies in [0, 8]
# the symbols scanned: stripes along an axis, q = 2 (1 - cos k) for k in [0, pi] (dense in k, so that every
# wavelength from 2 cells up has a point within a few per cent), then the rest of [4, 8] (diagonal wavevectors)
Q_GRID = np.concatenate([2 * (1 - np.cos(np.linspace(0.0, np.pi, 97))), np.linspace(4.0, Q_MAX, 17)[1:]])
REST_SHARE_MAX = 0.2  # the whole sheet's fastest mode: its largest |alpha| on the rest region over its peak


def law_growth(p: Params, q: np.ndarray, theory: Theory) -> np.ndarray:
    """Growth rates (complex, Re descending) of one uniform law at Laplacian symbols q: the lattice's dispersion at
    q (analysis.stability.growth_rates_at_q), with the theory's inertia and motor damping."""
    return growth_rates_at_q(p, q, inertia=theory.inertia, motor_damping=theory.motor_damping)


def edge_decay(p: Params) -> float:
    """How much of a static pattern's amplitude the rest law lets through per cell: the largest |exp(-mu)| over the
    static evanescent solutions (det(R - q K) = 0, cosh mu = 1 - q / 2); 1 when a static mode does not decay."""
    kab, sig, k2 = (float(p.per_cell(k)[0]) for k in ("k_ab", "sigma", "k2"))
    a11, a12, a21, a22 = -kab - k2, kab - sig, kab, -kab
    ka, kb = p.ka_eff, p.kb_eff
    roots = np.roots([ka * kb, -(a11 * kb + a22 * ka), a11 * a22 - a12 * a21])
    worst = 0.0
    for q in roots:
        mu = np.arccosh(complex(1.0 - q / 2.0))
        worst = max(worst, float(abs(np.exp(-abs(mu.real)))))
    return min(worst, 1.0)


def _region_law(p: Params, seg: np.ndarray, s: int) -> Params:
    """The scalar law of segment s (its first cell's: every cell of a segment holds the same)."""
    return p.cell(int(np.nonzero(seg == s)[0][0]) + 1)


def stripe_wavelength(q: float) -> float | None:
    """The wavelength (cells) of stripes along a lattice axis with symbol q (2 (1 - cos k) = q); None for q <= 0."""
    if q <= 0:
        return None
    return 2 * math.pi / math.acos(max(-1.0, 1.0 - q / 2.0)) if q <= 4 else 2.0


def sheet_linear_score(p: Params, target: SheetTarget) -> tuple[float, dict]:
    """(score, facts) of the regions' laws: > 1 when the pattern law's fastest wavevector is stationary, grows at
    least MIN_GROWTH_PER_S (its stripe wavelength within half of LAMBDA_TOL of a named one) and the rest law decays
    at every wavevector at least as fast, each also without the motors' back-EMF damping (the lattice theory: the
    rest law must not lean on the motors to rest); then 1 + (1 - edge_decay of the rest law) (the less of the
    pattern's edge it lets into the rest region, the better). Below 1: how far it is."""
    if not _shape_ok(p):
        return -3.0, {"why": "k1 <= max(k2, 0)"}
    th, lat = theory_of("hil", p), theory_of("lattice", p)  # lattice: the ideal law, no motors' damping
    seg = target.segments()
    pat, rest = _region_law(p, seg, 0), _region_law(p, seg, 1)
    q = Q_GRID
    gp = law_growth(pat, q, th)[:, 0]
    i = int(np.argmax(gp.real))
    g1 = float(gp[i].real)
    lam = stripe_wavelength(float(q[i]))
    facts: dict = {
        "pattern_growth_per_s": g1,
        "pattern_q": float(q[i]),
        "pattern_stripe_wavelength_cells": lam,
        "pattern_kind": "oscillatory" if abs(gp[i].imag) > 1e-9 * max(1.0, abs(gp[i])) else "stationary",
    }
    if facts["pattern_kind"] != "stationary":
        return -2.0 + 0.1 * math.tanh(-g1 / 50), facts
    if g1 < MIN_GROWTH_PER_S:
        return -1.0 + 0.5 * math.tanh(g1 / 20), facts
    gpl = law_growth(pat, q, lat)[:, 0]
    il = int(np.argmax(gpl.real))
    lat_osc = bool(abs(gpl[il].imag) > 1e-9 * max(1.0, abs(gpl[il])))
    rest_g = float(law_growth(rest, q, th)[:, 0].real.max())
    rest_gl = float(law_growth(rest, q, lat)[:, 0].real.max())
    decay = edge_decay(rest)
    facts.update(
        {
            "rest_growth_per_s": rest_g,
            "rest_edge_decay": decay,
            "rest_growth_lattice_per_s": rest_gl,
            "pattern_kind_lattice": "oscillatory" if lat_osc else "stationary",
        }
    )
    miss = max(0.0, rest_g + MIN_GROWTH_PER_S) / MIN_GROWTH_PER_S
    miss += max(0.0, rest_gl + MIN_GROWTH_PER_S) / MIN_GROWTH_PER_S + float(lat_osc)
    if target.lam is not None:
        off = abs((lam or 1e3) - target.lam) / target.lam
        miss += max(0.0, off - 0.5 * LAMBDA_TOL) * 4
    if miss:
        return 0.5 - 0.1 * min(miss, 10.0), facts
    return 2.0 - decay, facts


def sheet_first_guess(space: Space, target: SheetTarget, seed: int = 1, maxiter: int = 60):
    """Differential evolution on sheet_linear_score (scipy.optimize), from the base scene's values too (the chain's
    linear.evolve_score)."""
    return evolve_score(space, lambda p: sheet_linear_score(p, target), seed, maxiter)


def sheet_fastest_modes(p: Params, count: int = 2, theory: Theory | None = None) -> list[dict]:
    """The whole sheet's fastest linear modes with its per-cell laws (analysis.sheet_modes: the lattice linearised
    about rest, dense up to 100 cells, sparse shift-invert above; hil theory by default), fastest first."""
    return sheet_modes(p, theory or theory_of("hil", p), count=count)["modes"]


def mode_rest_share(alpha: np.ndarray, target: SheetTarget) -> float:
    """A mode's largest |alpha| on the rest region over its largest anywhere."""
    u = np.abs(np.asarray(alpha, dtype=float))
    return float(u[target.rest_mask()].max() / u.max())
