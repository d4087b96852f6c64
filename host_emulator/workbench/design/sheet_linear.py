"""Step 1 on a sheet, the first guess: each region's law from the square lattice's linear theory (the pattern law
grows, at the target's wavelength if it names one; the rest law decays at every wavevector and holds the pattern's
edge off its cells), then the whole sheet's eigenproblem as the check that its fastest mode lives in the pattern
region."""

from __future__ import annotations

import dataclasses
import math
from typing import Any

import numpy as np

from ...analysis.stability import Theory, theory_of
from ...params import Params
from .constants import MIN_GROWTH_PER_S
from .sheet_landing import LAMBDA_TOL
from .sheet_target import SheetTarget
from .space import Space, _shape_ok

Q_MAX = 8.0  # the square lattice's symbol 2 (2 - cos k_row - cos k_col) lies in [0, 8]
REST_SHARE_MAX = 0.2  # the whole sheet's fastest mode: its largest |alpha| on the rest region over its peak


def law_growth(p: Params, q: np.ndarray, theory: Theory) -> np.ndarray:
    """Growth rates (complex, (len(q), 4) with inertia or (len(q), 2), Re descending) of one uniform law (p's cell
    values, every per-cell value the same) at Laplacian symbols q: the 2-D lattice's dispersion, A(q) = R - q K."""
    q = np.atleast_1d(np.asarray(q, dtype=float))
    kab, sig, k2 = (float(p.per_cell(k)[0]) for k in ("k_ab", "sigma", "k2"))
    a = np.broadcast_to(np.array([[-kab - k2, kab - sig], [kab, -kab]]), (q.size, 2, 2)).copy()
    a[:, 0, 0] -= q * p.ka_eff
    a[:, 1, 1] -= q * p.kb_eff
    eta = np.array([p.eta_alpha, p.eta_beta]) + float(theory.motor_damping)
    if theory.inertia:
        inert = np.array([p.I_a, p.I_b])
        m = np.zeros((q.size, 4, 4))
        m[:, 0, 2] = m[:, 1, 3] = 1.0
        m[:, 2:, :2] = a / inert[None, :, None]
        m[:, 2, 2], m[:, 3, 3] = -eta[0] / inert[0], -eta[1] / inert[1]
    else:
        m = a / eta[None, :, None]
    ev = np.linalg.eigvals(m).astype(complex)
    order = np.lexsort((-ev.imag, -ev.real), axis=-1)
    return np.take_along_axis(ev, order, axis=-1)


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
    j = int(np.nonzero(seg == s)[0][0])
    kw: dict[str, Any] = {k: float(p.per_cell(k)[j]) for k in ("k_ab", "sigma", "k2", "k1", "alpha_star")}
    return dataclasses.replace(p, shape=(), lattice="chain", cells=1, **kw)


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
    th = theory_of("hil", p)
    seg = target.segments()
    q = np.linspace(0.0, Q_MAX, 41)
    gp = law_growth(_region_law(p, seg, 0), q, th)[:, 0]
    gr = law_growth(_region_law(p, seg, 1), q, th)[:, 0]
    i = int(np.argmax(gp.real))
    g1, rest_g = float(gp[i].real), float(gr.real.max())
    # the same laws without the motors' back-EMF damping (the lattice: the ideal law; a rig with compensation on)
    lat = theory_of("lattice", p)
    gpl = law_growth(_region_law(p, seg, 0), q, lat)[:, 0]
    rest_gl = float(law_growth(_region_law(p, seg, 1), q, lat)[:, 0].real.max())
    il = int(np.argmax(gpl.real))
    lat_osc = bool(abs(gpl[il].imag) > 1e-9 * max(1.0, abs(gpl[il])))
    lam = stripe_wavelength(float(q[i]))
    decay = edge_decay(_region_law(p, seg, 1))
    facts = {
        "pattern_growth_per_s": g1,
        "pattern_q": float(q[i]),
        "pattern_stripe_wavelength_cells": lam,
        "pattern_kind": "oscillatory" if abs(gp[i].imag) > 1e-9 * max(1.0, abs(gp[i])) else "stationary",
        "rest_growth_per_s": rest_g,
        "rest_edge_decay": decay,
        "rest_growth_lattice_per_s": rest_gl,
        "pattern_kind_lattice": "oscillatory" if lat_osc else "stationary",
    }
    if facts["pattern_kind"] != "stationary":
        return -2.0 + 0.1 * math.tanh(-g1 / 50), facts
    if g1 < MIN_GROWTH_PER_S:
        return -1.0 + 0.5 * math.tanh(g1 / 20), facts
    miss = max(0.0, rest_g + MIN_GROWTH_PER_S) / MIN_GROWTH_PER_S
    miss += max(0.0, rest_gl + MIN_GROWTH_PER_S) / MIN_GROWTH_PER_S + float(lat_osc)
    if target.lam is not None:
        off = abs((lam or 1e3) - target.lam) / target.lam
        miss += max(0.0, off - 0.5 * LAMBDA_TOL) * 4
    if miss:
        return 0.5 - 0.1 * min(miss, 10.0), facts
    return 2.0 - decay, facts


def sheet_first_guess(space: Space, target: SheetTarget, seed: int = 1, maxiter: int = 60):
    """Differential evolution on sheet_linear_score (scipy.optimize), from the base scene's values too."""
    from scipy.optimize import differential_evolution

    def f(x):
        return -sheet_linear_score(space.params(x), target)[0]

    rng = np.random.default_rng(seed)
    lo = np.array([b[0] for b in space.bounds])
    hi = np.array([b[1] for b in space.bounds])
    npop = max(15, 8 * len(lo))
    init = lo + (hi - lo) * rng.random((npop, len(lo)))
    init[0] = space.x0()
    r = differential_evolution(
        f, space.bounds, init=init, seed=seed, maxiter=maxiter, tol=1e-6, polish=False, updating="immediate"
    )
    x = np.asarray(r.x)
    score, facts = sheet_linear_score(space.params(x), target)
    return x, score, facts


def sheet_fastest_modes(p: Params, count: int = 2, theory: Theory | None = None) -> list[dict]:
    """The whole sheet's fastest linear modes (per-cell laws, free edges; hil theory by default): the eigenproblem
    of the lattice linearised about rest, I x'' + E x' = A x (docs/design.md), dense. Each {growth_per_s,
    imag_per_s, kind, alpha (cell order, largest entry +1)}, fastest first, conjugate pairs once."""
    th = theory or theory_of("hil", p)
    top = p.topology
    n = top.n
    lap = top.laplacian().toarray()
    kab, sig, k2 = p.per_cell("k_ab"), p.per_cell("sigma"), p.per_cell("k2")
    a = np.zeros((2 * n, 2 * n))
    a[:n, :n] = -p.ka_eff * lap + np.diag(-kab - k2)
    a[:n, n:] = np.diag(kab - sig)
    a[n:, :n] = np.diag(kab)
    a[n:, n:] = -p.kb_eff * lap + np.diag(-kab)
    e = np.concatenate([np.full(n, p.eta_alpha), np.full(n, p.eta_beta)]) + float(th.motor_damping)
    if th.inertia:
        inert = np.concatenate([np.full(n, p.I_a), np.full(n, p.I_b)])
        m = np.zeros((4 * n, 4 * n))
        m[: 2 * n, 2 * n :] = np.eye(2 * n)
        m[2 * n :, : 2 * n] = a / inert[:, None]
        m[2 * n :, 2 * n :] = -np.diag(e / inert)
    else:
        m = a / e[:, None]
    w, v = np.linalg.eig(m)
    order = np.lexsort((-w.imag, -w.real))
    out = []
    for k in order:
        s = w[k]
        if s.imag < -1e-9 * max(1.0, abs(s)):
            continue
        vec = v[:n, k]
        ph = vec[int(np.argmax(np.abs(vec)))]
        osc = bool(abs(s.imag) > 1e-9 * max(1.0, abs(s)))
        out.append(
            {
                "growth_per_s": float(s.real),
                "imag_per_s": float(abs(s.imag)),
                "kind": "oscillatory" if osc else "stationary",
                "alpha": (vec / ph).real,
            }
        )
        if len(out) >= count:
            break
    return out


def mode_rest_share(alpha: np.ndarray, target: SheetTarget) -> float:
    """A mode's largest |alpha| on the rest region over its largest anywhere."""
    u = np.abs(np.asarray(alpha, dtype=float))
    return float(u[target.rest_mask()].max() / u.max())
