"""Linear stability of the uniform rest state (docs/physics.md#linear-stability): growth rates, dispersion curve, band,
regime, Turing conditions.

Linearised about (alpha, beta) = (0, 0), a perturbation x = (alpha, beta) * exp(i kappa j + s t)
obeys, per unit cell (dimensional: torques in N m, angles in rad, time in s)::

    I s^2 x + E s x = A(q) x,     A(q) = Jr - q K,
    Jr = [[-k_ab - psi''(0), k_ab - sigma], [k_ab, -k_ab]]       (reaction Jacobian, dR/dx)
    K  = diag(ka_eff, kb_eff) = 2 band_scale diag(k_a, k_b)     (the simulated band law's slope)
    E  = diag(eta_a, eta_b),  I = diag(I_a, I_b)
    q  = kappa^2                 (continuum, kappa in rad per cell: lambda = 2 pi / kappa cells)
    q  = 2 (1 - cos kappa)       (discrete lattice, nearest-neighbour bands)

Without inertia the growth rates are the eigenvalues of E^-1 A(q); this equals the source's
(docs/physics.md#linear-stability) (J - q D) / eta_a with J = diag(1, 1/gamma) Jr and D = diag(ka_eff, kb_eff / gamma).
With inertia they are the four roots of det(I s^2 + E s - A(q)) = 0, i.e. the eigenvalues of the companion matrix
[[0, 1], [I^-1 A(q), -I^-1 E]].

A free-end chain of n cells (a missing neighbour pushes nothing) has the graph Laplacian of a path,
whose eigenvectors are cos(kappa (j - 1/2)) with kappa = pi m / n, m = 0..n-1; the cell-local reaction
does not mix them, so the chain's linear modes are exactly the dispersion curve sampled there.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import brentq, minimize_scalar

from ..physics import reaction_jacobian as _physics_jacobian

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from ..params import Params

__all__ = [
    "reaction_jacobian",
    "jacobian",
    "growth_rates",
    "turing_conditions",
    "dispersion",
    "plot_dispersion",
    "classify_regime",
    "q_of_kappa",
]

TWO_PI = 2.0 * math.pi


# ---- validation ---------------------------------------------------------------
def _check(params, inertia=False):
    """Reject parameters for which the linear system is not defined (clear error, nothing computed)."""
    bad = []
    for name, val in (
        ("eta_alpha", params.eta_alpha),
        ("eta_beta", params.eta_beta),
        ("ka_eff", params.ka_eff),
        ("kb_eff", params.kb_eff),
    ):
        if not (math.isfinite(val) and val > 0):
            bad.append(f"{name}={val!r} must be finite and > 0")
    for name in ("k_ab", "k1", "k2", "sigma"):
        val = getattr(params, name)
        if not math.isfinite(val):
            bad.append(f"{name}={val!r} must be finite")
    if inertia:
        for name in ("I_a", "I_b"):
            val = getattr(params, name)
            if not (math.isfinite(val) and val > 0):
                bad.append(f"{name}={val!r} must be finite and > 0 with inertia")
    if bad:
        raise ValueError("invalid parameters for stability analysis: " + "; ".join(bad))


def q_of_kappa(kappa: ArrayLike, discrete: bool = True) -> np.ndarray:
    """Laplacian symbol q(kappa): 2(1 - cos kappa) on the lattice, kappa^2 in the continuum."""
    k = np.asarray(kappa, dtype=float)
    return 2.0 * (1.0 - np.cos(k)) if discrete else k * k


# ---- Jacobians ----------------------------------------------------------------
def reaction_jacobian(params) -> np.ndarray:
    """dR/d(alpha, beta) at rest, N m / rad: [[-k_ab - k2, k_ab - sigma], [k_ab, -k_ab]] (psi''(0) = k2).

    Written beside the law in physics.py (physics.reaction_jacobian); this is its value at rest."""
    return _physics_jacobian(params)


def jacobian(params: Params) -> np.ndarray:
    """the source's (docs/physics.md#linear-stability) J (N m / rad, scaled by eta_a): [[-k_ab - k2, k_ab - sigma],
    [k_ab/gamma, -k_ab/gamma]].

    J = diag(1, 1/gamma) @ reaction_jacobian; growth rates without inertia are eig(J - q D) / eta_a with
    D = diag(ka_eff, kb_eff / gamma) (gamma = eta_b / eta_a).
    """
    jr = reaction_jacobian(params)
    jr[1, :] /= params.gamma
    return jr


# ---- growth rates ---------------------------------------------------------------
def _sort_desc(ev: np.ndarray) -> np.ndarray:
    """Sort each row by real part (descending); ties by imaginary part (descending, +Im first)."""
    order = np.lexsort((-ev.imag, -ev.real), axis=-1)
    return np.take_along_axis(ev, order, axis=-1)


def growth_rates(params: Params, kappa: ArrayLike, *, discrete: bool = True, inertia: bool = False) -> np.ndarray:
    """Growth rates s (1/s, complex) of mode kappa (rad per cell), shape (len(kappa), 2 or 4), Re descending."""
    _check(params, inertia)
    k = np.atleast_1d(np.asarray(kappa, dtype=float))
    if k.ndim != 1 or not np.all(np.isfinite(k)):
        raise ValueError("kappa must be a finite scalar or 1-D array")
    q = q_of_kappa(k, discrete)
    jr = reaction_jacobian(params)
    kd = np.array([params.ka_eff, params.kb_eff])
    eta = np.array([params.eta_alpha, params.eta_beta])
    # A(q) = Jr - q K, one 2x2 per kappa
    a = np.broadcast_to(jr, (k.size, 2, 2)).copy()
    a[:, 0, 0] -= q * kd[0]
    a[:, 1, 1] -= q * kd[1]
    if not inertia:
        m = a / eta[None, :, None]  # E^-1 A(q)
    else:
        inert = np.array([params.I_a, params.I_b])
        m = np.zeros((k.size, 4, 4))
        m[:, 0, 2] = m[:, 1, 3] = 1.0  # x' = v
        m[:, 2:, :2] = a / inert[None, :, None]  # I v' = A x - E v
        m[:, 2, 2] = -eta[0] / inert[0]
        m[:, 3, 3] = -eta[1] / inert[1]
    return _sort_desc(np.linalg.eigvals(m).astype(complex))


def _lead(params, kappa, discrete, inertia):
    """Leading (max real part) growth rate at scalar kappa."""
    return growth_rates(params, [kappa], discrete=discrete, inertia=inertia)[0, 0]


# ---- Turing conditions -----------------------------------------------------------
def turing_conditions(params: Params) -> dict:
    """The three Turing conditions of docs/physics.md#linear-stability in their explicit form for this reaction law.

    tr J < 0  <=>  k_ab (1 + 1/gamma) + k2 > 0        (uniform state stable to uniform perturbations, 1)
    det J > 0 <=>  k_ab (k2 + sigma) > 0               (... and to the non-oscillatory one, 2)
    -d k2 - k_ab (1 + d) > 2 sqrt(k_ab d (k2 + sigma)) (diffusion destabilises a finite band, 3)
    With psi''(0) = k2 (the inner branch). 'all' holds iff all three do (diffusion-driven instability).
    """
    _check(params)
    kab, k2, s, g, d = params.k_ab, params.k2, params.sigma, params.gamma, params.d
    c1 = kab * (1.0 + 1.0 / g) + k2
    c2 = kab * (k2 + s)
    lhs = -d * k2 - kab * (1.0 + d)
    rad = kab * d * (k2 + s)
    rhs = 2.0 * math.sqrt(rad) if rad >= 0 else float("nan")
    c3_holds = bool(rad >= 0 and lhs > rhs)
    out: dict[str, Any] = {
        "trace_negative": {"expr": "k_ab(1+1/gamma)+k2 > 0", "value": c1, "holds": bool(c1 > 0)},
        "det_positive": {"expr": "k_ab(k2+sigma) > 0", "value": c2, "holds": bool(c2 > 0)},
        "diffusion_driven": {
            "expr": "-d k2 - k_ab(1+d) > 2 sqrt(k_ab d (k2+sigma))",
            "value": lhs - rhs if rad >= 0 else None,
            "lhs": lhs,
            "rhs": rhs if rad >= 0 else None,
            "holds": c3_holds,
        },
    }
    out["all"] = bool(out["trace_negative"]["holds"] and out["det_positive"]["holds"] and c3_holds)
    return out


# ---- dispersion curve, band, regime ----------------------------------------------
def classify_regime(growth_at_zero: float, max_growth: float) -> str:
    """Regime rule (same for continuum and lattice, with and without inertia).

    stable: no mode grows (max Re s <= 0 over all kappa, including the uniform mode kappa = 0);
    unconditionally_unstable: the uniform / longest-wavelength mode grows (band reaches lambda -> inf);
    conditionally_unstable: some modes grow but the longest do not (a finite band: pattern selection).
    """
    if not max_growth > 0.0:
        return "stable"
    return "unconditionally_unstable" if growth_at_zero > 0.0 else "conditionally_unstable"


def _kappa_max(params, discrete, inertia):
    if discrete:
        return math.pi
    # continuum: from lambda = 1 cell, extended while the shortest wavelength still grows
    kmax = TWO_PI
    for _ in range(20):
        if _lead(params, kmax, False, inertia).real <= 0:
            return kmax
        kmax *= 2.0
    raise ValueError(
        "continuum growth rate stays positive at arbitrarily short wavelengths: "
        "check that k_a, k_b > 0 (diffusion must damp short waves)"
    )


def _lam(k):
    return None if k <= 0 else float(TWO_PI / k)


def _fin(x):
    x = float(x)
    return x if math.isfinite(x) else None


def dispersion(
    params: Params, *, inertia: bool = False, discrete: bool = True, n_cells: int | None = None, n_kappa: int = 2000
) -> dict:
    """Dispersion relation summary of the uniform state; see module docstring for the equations.

    fastest_lambda_cells: wavelength of the mode with the largest Re s (None if that is the uniform mode);
    fastest_growth_per_s: that Re s (negative when stable: the slowest decay);
    oscillation_period_s: 2 pi / |Im s| of that mode if it oscillates, else None;
    unstable_band_cells: [lo, hi] wavelengths (cells) with Re s > 0, hi None when it reaches lambda -> inf,
        lo = 2 on the lattice when it reaches the shortest wave; None when nothing grows.
    """
    _check(params, inertia)
    n_kappa = int(n_kappa)
    if n_kappa < 16:
        raise ValueError("n_kappa must be >= 16")
    kmax = _kappa_max(params, discrete, inertia)
    kap = np.linspace(0.0, kmax, n_kappa + 1)  # includes kappa = 0 (uniform mode)
    s = growth_rates(params, kap, discrete=discrete, inertia=inertia)[:, 0]
    re = s.real
    if not np.all(np.isfinite(s)):
        raise FloatingPointError("non-finite growth rate: parameters out of range")

    def f(k):
        return _lead(params, k, discrete, inertia).real

    # fastest mode, refined between grid neighbours
    i = int(np.argmax(re))
    k_best, s_best = kap[i], s[i]
    if 0 < i < len(kap) - 1:
        r = minimize_scalar(
            lambda k: -f(k), bounds=(kap[i - 1], kap[i + 1]), method="bounded", options={"xatol": 1e-10}
        )
        if -r.fun >= re[i]:
            k_best = float(r.x)
            s_best = _lead(params, k_best, discrete, inertia)
    fastest_growth = float(s_best.real)

    # unstable band: sign changes of Re s, refined by brentq
    pos = re > 0
    band = None
    if pos.any():
        edges = []
        for j in np.nonzero(pos[1:] != pos[:-1])[0]:
            edges.append(brentq(f, kap[j], kap[j + 1], xtol=1e-12))
        k_lo_edge = 0.0 if pos[0] else min(edges)
        k_hi_edge = kmax if pos[-1] else max(edges)
        hi = None if pos[0] else _lam(k_lo_edge)
        lo = _lam(k_hi_edge)
        band = [lo, hi]
    band_note = "several disjoint unstable bands; reported their envelope" if pos.any() and len(edges) > 2 else None

    regime = classify_regime(float(re[0]), float(re.max()))
    osc = abs(s_best.imag)
    out: dict[str, Any] = {
        "model": "discrete" if discrete else "continuum",
        "inertia": bool(inertia),
        "sigma": float(params.sigma),
        "regime": regime,
        "fastest_lambda_cells": _lam(k_best) if k_best > 1e-9 else None,
        "fastest_kappa": float(k_best),
        "fastest_growth_per_s": fastest_growth,
        "oscillation_period_s": (TWO_PI / osc) if osc > 1e-9 * max(1.0, abs(s_best)) else None,
        "uniform_mode_growth_per_s": float(re[0]),
        "uniform_mode_period_s": (TWO_PI / abs(s[0].imag)) if abs(s[0].imag) > 1e-9 * max(1.0, abs(s[0])) else None,
        "unstable_band_cells": band,
        "turing": turing_conditions(params),
        "curve": {
            "lambda_cells": [TWO_PI / k for k in kap[1:]],
            "growth_per_s": [float(x) for x in re[1:]],
            "imag_per_s": [float(abs(x)) for x in s[1:].imag],
        },
    }
    if band_note:
        out["band_note"] = band_note
    if n_cells is not None:
        n = int(n_cells)
        if n < 1:
            raise ValueError("n_cells must be >= 1")
        km = np.pi * np.arange(n) / n
        sm = growth_rates(params, km, discrete=discrete, inertia=inertia)[:, 0]
        out["lattice_modes"] = [
            {
                "m": m,
                "kappa": float(km[m]),
                "lambda_cells": _lam(km[m]) if m else None,
                "growth_per_s": float(sm[m].real),
                "imag_per_s": float(abs(sm[m].imag)),
            }
            for m in range(n)
        ]
        mbest = int(np.argmax(sm.real))
        out["lattice_fastest_mode"] = out["lattice_modes"][mbest]
    return out


# ---- plot -------------------------------------------------------------------------
def plot_dispersion(params: Params, ax: Axes | None = None, *, inertia: bool = False) -> Axes:
    """Re s(lambda) for the lattice and the continuum (Im s dashed), band shaded, chain modes marked.

    Uses matplotlib's object API (no pyplot) so it is safe under any backend; returns the Axes.
    """
    if ax is None:
        from matplotlib.figure import Figure

        ax = Figure(figsize=(6.4, 4.0)).add_subplot(111)
    n = int(getattr(params, "cells", 16) or 16)
    disc = dispersion(params, inertia=inertia, discrete=True, n_cells=n, n_kappa=800)
    cont = dispersion(params, inertia=inertia, discrete=False, n_kappa=800)
    for res, style, label in ((disc, "C0", "lattice"), (cont, "C1", "continuum")):
        lam = np.asarray(res["curve"]["lambda_cells"])
        ax.plot(lam, res["curve"]["growth_per_s"], color=style, label=f"Re s, {label}")
        im = np.asarray(res["curve"]["imag_per_s"], dtype=float)
        ytop = 1.3 * max(abs(disc["fastest_growth_per_s"]), abs(cont["fastest_growth_per_s"]), 1e-9)
        im = np.where((im > 0) & (im <= ytop), im, np.nan)  # off-scale |Im s| is not drawn as spikes
        if np.any(np.isfinite(im)):
            ax.plot(lam, im, color=style, ls="--", lw=0.8, label=f"|Im s|, {label}")
    band = disc["unstable_band_cells"]
    if band:
        ax.axvspan(
            band[0],
            band[1] if band[1] is not None else 1e3,
            color="C0",
            alpha=0.12,
            label=f"unstable band {band[0]:.3g}-{'inf' if band[1] is None else format(band[1], '.3g')} cells",
        )
    modes = [m for m in disc["lattice_modes"] if m["lambda_cells"]]
    ax.plot(
        [m["lambda_cells"] for m in modes],
        [m["growth_per_s"] for m in modes],
        "o",
        ms=3,
        color="C0",
        label=f"free-end modes, {n} cells",
    )
    if disc["fastest_lambda_cells"]:
        ax.axvline(
            disc["fastest_lambda_cells"],
            color="C0",
            lw=0.8,
            ls=":",
            label=f"fastest wavelength {disc['fastest_lambda_cells']:.3g} cells",
        )
    ax.axhline(0.0, color="k", lw=0.5)
    ax.set_xscale("log")
    ax.set_xlim(1.8, 4 * n)
    from matplotlib.ticker import FixedLocator, FormatStrFormatter, NullFormatter

    ax.xaxis.set_major_locator(
        FixedLocator([t for t in (2, 3, 5, 7.5, 10, 15, 20, 30, 60, 120, 250, 500) if t <= 4 * n])
    )  # no colliding log-axis labels
    ax.xaxis.set_major_formatter(FormatStrFormatter("%g"))
    ax.xaxis.set_minor_formatter(NullFormatter())
    ylo = min(np.percentile(disc["curve"]["growth_per_s"], 5), -abs(disc["fastest_growth_per_s"]))
    ax.set_ylim(ylo, 1.3 * max(abs(disc["fastest_growth_per_s"]), abs(cont["fastest_growth_per_s"]), 1e-9))
    ax.set_xlabel("wavelength lambda (cells)")
    ax.set_ylabel("growth rate (1/s)")
    ax.set_title(
        f"sigma = {params.sigma:.4g}: {disc['regime'].replace('_', ' ')}{' (inertia)' if inertia else ''}", fontsize=10
    )
    ax.legend(fontsize=7, loc="lower right")
    return ax
