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
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike
from scipy.optimize import minimize_scalar

from ..physics import reaction_jacobian as _physics_jacobian

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from ..params import Params

__all__ = [
    "reaction_jacobian",
    "jacobian",
    "growth_rates",
    "growth_rates_at_q",
    "turing_conditions",
    "dispersion",
    "plot_dispersion",
    "classify_regime",
    "q_of_kappa",
    "REGIMES",
    "Theory",
    "theory_of",
    "motor_damping",
    "format_set",
]

TWO_PI = 2.0 * math.pi


# ---- validation ---------------------------------------------------------------
def _check(params, inertia=False):
    """Reject parameters for which the linear system is not defined (clear error, nothing computed); per-cell
    parameters must agree between cells (a chain whose cells differ has no dispersion relation: analysis.chain)."""
    if hasattr(params, "varying_keys") and params.varying_keys:
        params.value(params.varying_keys[0])  # raises, naming the key
    if hasattr(params, "uniform"):
        params = params.uniform()
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


def growth_rates(
    params: Params, kappa: ArrayLike, *, discrete: bool = True, inertia: bool = False, motor_damping: float = 0.0
) -> np.ndarray:
    """Growth rates s (1/s, complex) of mode kappa (rad per cell), shape (len(kappa), 2 or 4), Re descending.

    motor_damping (N m s) adds to both viscous coefficients (the hil motors' back-EMF, see theory_of)."""
    _check(params, inertia)
    k = np.atleast_1d(np.asarray(kappa, dtype=float))
    if k.ndim != 1 or not np.all(np.isfinite(k)):
        raise ValueError("kappa must be a finite scalar or 1-D array")
    return growth_rates_at_q(params, q_of_kappa(k, discrete), inertia=inertia, motor_damping=motor_damping)


def growth_rates_at_q(params: Params, q: ArrayLike, *, inertia: bool = False, motor_damping: float = 0.0) -> np.ndarray:
    """Growth rates s (1/s, complex) of the modes whose Laplacian eigenvalue is q (>= 0), shape (len(q), 2 or 4).

    The Laplacian enters the linear problem only through its eigenvalue, so this is the growth rate of any lattice
    (a chain, a square or hexagonal sheet: analysis.sheet) at a wavevector whose symbol is q."""
    _check(params, inertia)
    q = np.atleast_1d(np.asarray(q, dtype=float))
    if q.ndim != 1 or not np.all(np.isfinite(q)):
        raise ValueError("q must be a finite scalar or 1-D array")
    jr = reaction_jacobian(params)
    kd = np.array([params.ka_eff, params.kb_eff])
    eta = np.array([params.eta_alpha, params.eta_beta]) + float(motor_damping)
    # A(q) = Jr - q K, one 2x2 per q
    a = np.broadcast_to(jr, (q.size, 2, 2)).copy()
    a[:, 0, 0] -= q * kd[0]
    a[:, 1, 1] -= q * kd[1]
    if not inertia:
        m = a / eta[None, :, None]  # E^-1 A(q)
    else:
        inert = np.array([params.I_a, params.I_b])
        m = np.zeros((q.size, 4, 4))
        m[:, 0, 2] = m[:, 1, 3] = 1.0  # x' = v
        m[:, 2:, :2] = a / inert[None, :, None]  # I v' = A x - E v
        m[:, 2, 2] = -eta[0] / inert[0]
        m[:, 3, 3] = -eta[1] / inert[1]
    return _sort_desc(np.linalg.eigvals(m).astype(complex))


def _lead(params, kappa, discrete, inertia, damping=0.0):
    """Leading (max real part) growth rate at scalar kappa."""
    return growth_rates(params, [kappa], discrete=discrete, inertia=inertia, motor_damping=damping)[0, 0]


# ---- Turing conditions -----------------------------------------------------------
def turing_conditions(params: Params) -> dict:
    """The three Turing conditions of docs/physics.md#linear-stability in their explicit form for this reaction law.

    tr J < 0  <=>  k_ab (1 + 1/gamma) + k2 > 0        (uniform state stable to uniform perturbations, 1)
    det J > 0 <=>  k_ab (k2 + sigma) > 0               (... and to the non-oscillatory one, 2)
    -d k2 - k_ab (1 + d) > 2 sqrt(k_ab d (k2 + sigma)) (diffusion destabilises a finite band, 3)
    With psi''(0) = k2 (the inner branch). 'all' holds iff all three do (diffusion-driven instability).
    """
    _check(params)
    kab, k2, s, g, d = params.value("k_ab"), params.value("k2"), params.value("sigma"), params.gamma, params.d
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


# ---- the theory of a model, regimes, unstable sets ---------------------------------
BEMF_COMP_FRACTION = 15 / 16  # the firmware's back-EMF compensation: MC_BEMF_FRAC_NUM / MC_BEMF_FRAC_DEN (mc_drive.h)

REGIMES = {
    "rest": "no mode grows: every perturbation of the rest state decays",
    "stationary_pattern": "only stationary modes (real s > 0) grow, in bands of finite wavelength "
    "(Turing: the lattice selects a pattern)",
    "broadband_pattern": "only stationary modes grow, and the unstable set reaches the longest waves "
    "(lambda -> inf: the uniform mode grows too)",
    "uniform_oscillation": "only oscillatory modes (complex s, Re s > 0) grow, the uniform mode among them",
    "pattern_and_oscillation": "stationary and oscillatory modes both grow, in separate intervals",
}


@dataclass(frozen=True)
class Theory:
    """The linear theory of one model: inertia or not, lattice (q = 2(1 - cos kappa)) or continuum (q = kappa^2),
    and a viscous coefficient added on every cylinder (N m s: the hil motors' uncompensated back-EMF)."""

    model: str = "lattice"
    inertia: bool = True
    discrete: bool = True
    motor_damping: float = 0.0

    def label(self) -> str:
        """What the theory includes, e.g. 'lattice with inertia' or 'hil: lattice with inertia + the motors'
        back-EMF damping 1.5e-04 N m s'."""
        text = f"{'lattice' if self.discrete else 'continuum'} {'with' if self.inertia else 'without'} inertia"
        if self.motor_damping > 0:
            text += f" + the motors' back-EMF damping {self.motor_damping:.1e} N m s"
        return (f"{self.model}: " if self.model not in ("lattice", "continuum") else "") + text


def motor_damping(params: Params) -> float:
    """Viscous coefficient (N m s) the hil model's motors add on every cylinder: Kt/S_L, of which the firmware's
    back-EMF compensation (params.bemf_comp) removes 15/16."""
    return params.eta_bemf * ((1.0 - BEMF_COMP_FRACTION) if params.bemf_comp else 1.0)


def theory_of(model: str, params: Params, inertia: bool = True) -> Theory:
    """The linear theory of a scene's model: the continuum model has no inertia; the lattice model has the scene's
    inertia switch; the hil model is the lattice plus its motors' back-EMF damping (firmware quantisation and
    sampling are not in the linear theory); so is the image model (the same motors, driven by the flashed images)."""
    if model == "continuum":
        return Theory("continuum", False, False, 0.0)
    if model in ("hil", "image"):
        return Theory(model, bool(inertia), True, motor_damping(params))
    return Theory(model, bool(inertia), True, 0.0)


def classify_regime(intervals: list[dict]) -> str:
    """The regime named for what grows (REGIMES; docs/analysis.md#regimes), from the unstable intervals of
    `dispersion` (each with its kind, stationary or oscillatory, and its kappa range)."""
    stat = [iv for iv in intervals if iv["kind"] == "stationary"]
    osc = [iv for iv in intervals if iv["kind"] == "oscillatory"]
    if stat and osc:
        return "pattern_and_oscillation"
    if osc:
        return "uniform_oscillation"
    if stat:
        return "broadband_pattern" if any(iv["kappa"][0] == 0.0 for iv in stat) else "stationary_pattern"
    return "rest"


def _kappa_max(params, discrete, inertia, damping=0.0):
    if discrete:
        return math.pi
    # continuum: from lambda = 1 cell, extended while the shortest wavelength still grows
    kmax = TWO_PI
    for _ in range(20):
        if _lead(params, kmax, False, inertia, damping).real <= 0:
            return kmax
        kmax *= 2.0
    raise ValueError(
        "continuum growth rate stays positive at arbitrarily short wavelengths: "
        "check that k_a, k_b > 0 (diffusion must damp short waves)"
    )


def _lam(k):
    return None if k <= 0 else float(TWO_PI / k)


def _is_osc(s) -> bool:
    """A growth rate is oscillatory when its imaginary part is not a rounding residue."""
    return bool(abs(s.imag) > 1e-9 * max(1.0, abs(s)))


def _kind_growth(rates: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Per kappa (rows of growth_rates): the largest Re s among the stationary (real) roots and among the
    oscillatory (complex) roots; -inf where that kind has no root."""
    osc = np.abs(rates.imag) > 1e-9 * np.maximum(1.0, np.abs(rates))
    re = rates.real
    g_stat = np.where(~osc, re, -np.inf).max(axis=1)
    g_osc = np.where(osc, re, -np.inf).max(axis=1)
    return g_stat, g_osc


def _unstable_intervals(params, kap, rates, kmax, discrete, inertia, damping) -> list[dict]:
    """The kappa intervals where a stationary mode (a real root, Re s > 0) or an oscillatory one (a complex root)
    grows, each kind on its own (both can grow at one kappa: every root counts, not only the fastest); edges
    bisected to 1e-15 between grid points, each interval with its fastest root."""

    def g(k: float, kind: int) -> float:
        return float(
            _kind_growth(growth_rates(params, [k], discrete=discrete, inertia=inertia, motor_damping=damping))[kind][0]
        )

    def edge(a: float, b: float, kind: int, grows_at_a: bool) -> float:
        for _ in range(64):
            m = 0.5 * (a + b)
            if m in (a, b):
                break
            if (g(m, kind) > 0) == grows_at_a:
                a = m
            else:
                b = m
        return a if grows_at_a else b

    out: list[dict] = []
    n = len(kap)
    for kind, gk in enumerate(_kind_growth(rates)):
        name = ("stationary", "oscillatory")[kind]
        pos = gk > 0
        i = 0
        while i < n:
            if not pos[i]:
                i += 1
                continue
            j = i
            while j + 1 < n and pos[j + 1]:
                j += 1
            k_lo = 0.0 if i == 0 else edge(float(kap[i]), float(kap[i - 1]), kind, True)
            k_hi = float(kmax) if j == n - 1 else edge(float(kap[j]), float(kap[j + 1]), kind, True)
            b_i = i + int(np.argmax(gk[i : j + 1]))
            k_best, g_best = float(kap[b_i]), float(gk[b_i])
            lo_b, hi_b = max(k_lo, float(kap[max(b_i - 1, 0)])), min(k_hi, float(kap[min(b_i + 1, n - 1)]))
            if hi_b > lo_b:
                r = minimize_scalar(
                    lambda k, kind=kind: -g(k, kind), bounds=(lo_b, hi_b), method="bounded", options={"xatol": 1e-10}
                )
                if -r.fun > g_best * (1 + 1e-12):
                    k_best, g_best = float(r.x), float(-r.fun)
            row = growth_rates(params, [k_best], discrete=discrete, inertia=inertia, motor_damping=damping)[0]
            of_kind = [z for z in row if _is_osc(z) == bool(kind)]
            best = max(of_kind, key=lambda z: z.real) if of_kind else row[0]
            out.append(
                {
                    "lambda_cells": [_lam(k_hi), _lam(k_lo)],
                    "kappa": [k_lo, k_hi],
                    "kind": name,
                    "fastest_lambda_cells": _lam(k_best) if k_best > 1e-9 * max(1.0, kmax) else None,
                    "fastest_growth_per_s": g_best,
                    "period_s": float(TWO_PI / abs(best.imag)) if kind == 1 and _is_osc(best) else None,
                }
            )
            i = j + 1
    out.sort(key=lambda iv: (-iv["kappa"][1], iv["kind"]))  # shortest wavelengths first
    return out


def _merged(intervals: list[dict]) -> list[list[float | None]]:
    """The unstable set as disjoint [lo, hi] wavelength intervals (cells; hi None = reaches lambda -> inf)."""
    spans = sorted((iv["kappa"] for iv in intervals), key=lambda k: k[0])
    merged: list[list[float]] = []
    for lo, hi in spans:
        if merged and lo <= merged[-1][1] + 1e-12:
            merged[-1][1] = max(merged[-1][1], hi)
        else:
            merged.append([lo, hi])
    return [[_lam(hi), _lam(lo)] for lo, hi in reversed(merged)]


def format_set(cells: list | None) -> str:
    """'[4.51, 7.54] U [19.27, inf)' for an unstable set (cells), 'none' when empty."""
    if not cells:
        return "none"
    return " U ".join(f"[{lo:.2f}, inf)" if hi is None else f"[{lo:.2f}, {hi:.2f}]" for lo, hi in cells)


def dispersion(
    params: Params,
    *,
    inertia: bool = False,
    discrete: bool = True,
    n_cells: int | None = None,
    n_kappa: int = 2000,
    motor_damping: float = 0.0,
    theory: Theory | None = None,
) -> dict:
    """Dispersion relation summary of the uniform state; see module docstring for the equations.

    theory: a Theory (theory_of(model, params, inertia)) sets inertia, discrete and motor_damping at once.
    regime: one of REGIMES (classify_regime); unstable_set_cells: the wavelengths (cells) that grow, as a union of
        disjoint [lo, hi] intervals (hi None: reaches lambda -> inf; lo = 2 on the lattice at the shortest wave),
        [] when nothing grows; unstable_intervals: the same split by kind (stationary / oscillatory), each with
        its fastest mode and, if oscillatory, its period;
    fastest_lambda_cells: wavelength of the mode with the largest Re s (None if that is the uniform mode);
    fastest_growth_per_s: that Re s (negative when nothing grows: the slowest decay);
    oscillation_period_s: 2 pi / |Im s| of that mode if it oscillates, else None.
    """
    if theory is not None:
        inertia, discrete, motor_damping = theory.inertia, theory.discrete, theory.motor_damping
    else:
        theory = Theory("lattice" if discrete else "continuum", bool(inertia), bool(discrete), float(motor_damping))
    _check(params, inertia)
    if not (math.isfinite(motor_damping) and motor_damping >= 0):
        raise ValueError(f"motor_damping={motor_damping!r} must be finite and >= 0")
    n_kappa = int(n_kappa)
    if n_kappa < 16:
        raise ValueError("n_kappa must be >= 16")
    damp = float(motor_damping)
    kmax = _kappa_max(params, discrete, inertia, damp)
    kap = np.linspace(0.0, kmax, n_kappa + 1)  # includes kappa = 0 (uniform mode)
    s = growth_rates(params, kap, discrete=discrete, inertia=inertia, motor_damping=damp)[:, 0]
    re = s.real
    if not np.all(np.isfinite(s)):
        raise FloatingPointError("non-finite growth rate: parameters out of range")

    def f(k):
        return _lead(params, k, discrete, inertia, damp).real

    # fastest mode, refined between grid neighbours
    i = int(np.argmax(re))
    k_best, s_best = kap[i], s[i]
    if 0 < i < len(kap) - 1:
        r = minimize_scalar(
            lambda k: -f(k), bounds=(kap[i - 1], kap[i + 1]), method="bounded", options={"xatol": 1e-10}
        )
        if -r.fun >= re[i]:
            k_best = float(r.x)
            s_best = _lead(params, k_best, discrete, inertia, damp)
    if i <= 1 and k_best > 0 and re[0] >= s_best.real - 1e-9 * abs(s_best):
        k_best, s_best = 0.0, s[0]
    fastest_growth = float(s_best.real)

    intervals = _unstable_intervals(
        params,
        kap,
        growth_rates(params, kap, discrete=discrete, inertia=inertia, motor_damping=damp),
        kmax,
        discrete,
        inertia,
        damp,
    )
    regime = classify_regime(intervals)
    osc = abs(s_best.imag)
    out: dict[str, Any] = {
        "model": "discrete" if discrete else "continuum",
        "inertia": bool(inertia),
        "theory": theory.label(),
        "motor_damping_Nms": damp,
        "sigma": params.value("sigma"),
        "regime": regime,
        "fastest_lambda_cells": _lam(k_best) if k_best > 1e-9 else None,
        "fastest_kappa": float(k_best),
        "fastest_growth_per_s": fastest_growth,
        "oscillation_period_s": (TWO_PI / osc) if osc > 1e-9 * max(1.0, abs(s_best)) else None,
        "uniform_mode_growth_per_s": float(re[0]),
        "uniform_mode_period_s": (TWO_PI / abs(s[0].imag)) if abs(s[0].imag) > 1e-9 * max(1.0, abs(s[0])) else None,
        "unstable_set_cells": _merged(intervals),
        "unstable_intervals": [{k: v for k, v in iv.items() if k != "kappa"} for iv in intervals],
        "turing": turing_conditions(params),
        "curve": {
            "lambda_cells": [TWO_PI / k for k in kap[1:]],
            "growth_per_s": [float(x) for x in re[1:]],
            "imag_per_s": [float(abs(x)) for x in s[1:].imag],
        },
    }
    if n_cells is not None:
        n = int(n_cells)
        if n < 1:
            raise ValueError("n_cells must be >= 1")
        km = np.pi * np.arange(n) / n
        sm = growth_rates(params, km, discrete=discrete, inertia=inertia, motor_damping=damp)[:, 0]
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
def plot_dispersion(
    params: Params, ax: Axes | None = None, *, inertia: bool = False, theory: Theory | None = None
) -> Axes:
    """Re s(lambda) (1/s, absolute) for the lattice and the continuum (|Im s| dashed), every unstable interval
    shaded (stationary blue, oscillatory red hatched), chain modes marked; the theory is named in the title.

    theory: a Theory (theory_of(model, ...)); without it, the lattice with/without inertia. Uses matplotlib's
    object API (no pyplot) so it is safe under any backend; returns the Axes.
    """
    if ax is None:
        from matplotlib.figure import Figure

        ax = Figure(figsize=(6.4, 4.0)).add_subplot(111)
    if theory is None:
        theory = Theory("lattice", bool(inertia), True, 0.0)
    n = int(getattr(params, "cells", 16) or 16)
    cont_theory = Theory(theory.model, theory.inertia, False, theory.motor_damping)
    disc = dispersion(
        params, theory=Theory(theory.model, theory.inertia, True, theory.motor_damping), n_cells=n, n_kappa=800
    )
    cont = dispersion(params, theory=cont_theory, n_kappa=800)
    ytop = 1.3 * max(abs(disc["fastest_growth_per_s"]), abs(cont["fastest_growth_per_s"]), 1e-9)
    for res, style, label in ((disc, "C0", "lattice"), (cont, "C1", "continuum")):
        lam = np.asarray(res["curve"]["lambda_cells"])
        ax.plot(lam, res["curve"]["growth_per_s"], color=style, label=f"Re s, {label}")
        im = np.asarray(res["curve"]["imag_per_s"], dtype=float)
        im = np.where((im > 0) & (im <= ytop), im, np.nan)  # off-scale |Im s| is not drawn as spikes
        if np.any(np.isfinite(im)):
            ax.plot(lam, im, color=style, ls="--", lw=0.8, label=f"|Im s|, {label}")
    for iv in disc["unstable_intervals"]:
        lo, hi = iv["lambda_cells"]
        osc = iv["kind"] == "oscillatory"
        ax.axvspan(
            lo,
            hi if hi is not None else 1e3,
            color="C3" if osc else "C0",
            alpha=0.12,
            hatch="//" if osc else None,
            label=f"{iv['kind']} unstable {lo:.3g}-{'inf' if hi is None else format(hi, '.3g')} cells",
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
    ax.set_ylim(ylo, ytop)
    ax.set_xlabel("wavelength lambda (cells)")
    ax.set_ylabel("growth rate Re s (1/s); |Im s| dashed")
    ax.set_title(
        f"sigma = {params.sigma:.4g}: {disc['regime'].replace('_', ' ')}\nlinear theory: {theory.label()}",
        fontsize=9,
    )
    ax.legend(fontsize=6, loc="lower right")
    return ax
