"""Linear theory of a whole chain, heterogeneous or not: the eigenproblem of the lattice's Jacobian at rest.

With one reaction law per cell (Params.per_cell), the chain's linear modes are no longer the cosines of the
uniform chain (analysis.stability, docs/analysis.md), so the linear theory is the eigenproblem of the whole
lattice linearised about rest (x = alpha_1..alpha_n, beta_1..beta_n; angles in rad, torques in N m)::

    I x'' + E x' = A x,      A = R - K
    R = [[diag(-k_ab_j - k2_j), diag(k_ab_j - sigma_j)], [diag(k_ab_j), diag(-k_ab_j)]]   (each cell's dR/dx)
    K = blockdiag(ka_eff L_a, kb_eff L_b)    (L: the free-end path Laplacian, bond j weighted by its stiffness
                                              factor: 1, or the noise model's band spread)
    E = diag(eta_a,j + m, eta_b,j + m)       (m: the hil motors' back-EMF damping, theory.motor_damping)
    I = diag(I_a, I_b)

Without inertia the growth rates are the eigenvalues of E^-1 A; with inertia those of the companion matrix
[[0, 1], [I^-1 A, -I^-1 E]] (2 per cylinder). When every cell has the same law this is block-diagonalised by
the cosines cos(pi m (j - 1/2) / n): the growth rates are those of analysis.stability.growth_rates at
kappa = pi m / n, m = 0..n-1, which tests/host_emulator/analysis/test_chain.py checks.

Each mode's shape is read as the rig's patterns are (analysis.observables): its alpha part, scaled to a largest
entry of 1, has domain walls where it changes sign among the cells above a tenth of that largest entry.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import numpy as np

from ..topology import Topology
from .sheet_modes import dense_eig, distinct_modes, mode_rates, sheet_matrices
from .stability import Theory, classify_regime

if TYPE_CHECKING:
    from ..params import Params
    from .stability import Theory

__all__ = ["chain_matrices", "chain_modes", "chain_summary", "mode_walls", "WALL_FRACTION"]

WALL_FRACTION = 0.1  # cells whose |alpha| is below this share of the largest take no part in a mode's wall count


def chain_matrices(
    params: Params,
    theory: Theory | None = None,
    *,
    band_factors: np.ndarray | None = None,
    eta_factors: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(A, E, I) of the module docstring, each (2n, 2n) (E and I diagonal), in N m/rad, N m s, kg m^2.

    band_factors, eta_factors: (2, n) stiffness factors of each bond (the last column unused) and viscosity
    factors of each cylinder, as models.plant.spreads draws them for the noise model (default: all 1).
    The general lattice's sheet_modes.sheet_matrices on the free-end chain (bond j = (j, j+1))."""
    n = params.cells
    band = np.ones((2, n)) if band_factors is None else np.asarray(band_factors, dtype=float)
    eta = np.ones((2, n)) if eta_factors is None else np.asarray(eta_factors, dtype=float)
    if band.shape != (2, n) or eta.shape != (2, n):
        raise ValueError(f"band_factors and eta_factors must have shape (2, {n})")
    a, e, i = sheet_matrices(params, theory, band_factors=band[:, : n - 1], eta_factors=eta, topology=Topology.chain(n))
    return a, np.diag(e), np.diag(i)


def mode_walls(profile: np.ndarray, fraction: float = WALL_FRACTION) -> list[float]:
    """Bond positions (j + 0.5 between cells j and j + 1, 1-based) where a profile changes sign among its cells
    above `fraction` of its largest |entry|; the position is the zero of the straight line between the two."""
    u = np.asarray(profile, dtype=float)
    big = np.abs(u).max()
    if not big > 0:
        return []
    idx = np.nonzero(np.abs(u) > fraction * big)[0]
    out = []
    for a, b in zip(idx[:-1], idx[1:]):
        if np.sign(u[a]) != np.sign(u[b]):
            x = a + (b - a) * u[a] / (u[a] - u[b])  # 0-based position of the zero
            out.append(float(x) + 1.0)
    return out


def chain_modes(params: Params, theory: Theory | None = None, *, count: int | None = None, **factors: Any) -> dict:
    """The chain's linear modes, fastest first (complex-conjugate pairs once, +Im first).

    Returns {"growth_per_s": complex array of every eigenvalue (Re descending), "modes": [one dict per distinct mode
    (up to `count`): growth_per_s (Re s), imag_per_s (|Im s|), period_s (oscillatory) or None, kind ("stationary"
    or "oscillatory"), alpha (the alpha part of its eigenvector, real, largest entry +1), walls (mode_walls),
    domain_walls (their number), lambda_cells (2 (n - 1) / Z, the rig's reading; None for Z = 0), dct_m (its
    largest cosine component: the uniform chain's mode index) and dct_lambda_cells (2 n / m; None for m = 0)]}.
    factors: band_factors, eta_factors of chain_matrices."""
    from scipy.fft import dct

    theory = theory or Theory("lattice", True, True, 0.0)
    a, e, i = chain_matrices(params, theory, **factors)
    n = params.cells
    w, v = dense_eig(a, np.diag(e), np.diag(i), theory.inertia)
    modes = []
    for s, alpha in distinct_modes(w, v, n):
        walls = mode_walls(alpha)
        c = dct(alpha, type=2, norm="ortho")
        dm = int(np.argmax(np.abs(c)))
        modes.append(
            {
                **mode_rates(s),
                "alpha": alpha,
                "walls": walls,
                "domain_walls": len(walls),
                "lambda_cells": 2.0 * (n - 1) / len(walls) if walls else None,
                "dct_m": dm,
                "dct_lambda_cells": 2.0 * n / dm if dm else None,
            }
        )
        if count is not None and len(modes) >= count:
            break
    return {"growth_per_s": w, "modes": modes}


def chain_summary(params: Params, theory: Theory) -> dict:
    """The linear-theory keys of summary.json (analysis.summary.DISPERSION_KEYS) for a chain whose cells differ:
    the chain's modes in place of the dispersion curve. unstable_intervals lists every growing mode as a point
    interval at its cosine wavelength 2 n / m (the uniform chain's reading of the same mode); unstable_set_cells
    each such wavelength once."""
    res = chain_modes(params, theory)
    modes = res["modes"]
    grow = [md for md in modes if md["growth_per_s"] > 0]
    intervals = []
    for md in grow:
        lam = md["dct_lambda_cells"]
        intervals.append(
            {
                "lambda_cells": [lam, lam],
                "kappa": [math.pi * md["dct_m"] / params.cells] * 2,
                "kind": md["kind"],
                "fastest_lambda_cells": lam,
                "fastest_growth_per_s": md["growth_per_s"],
                "period_s": md["period_s"],
                "domain_walls": md["domain_walls"],
                "walls": md["walls"],
            }
        )
    regime = classify_regime(intervals)
    top = modes[0]
    what = "lattice with inertia" if theory.inertia else "lattice without inertia"
    if theory.motor_damping > 0:
        what += f" + the motors' back-EMF damping {theory.motor_damping:.1e} N m s"
    label = f"{theory.model}: eigenmodes of the chain, {what} (per-cell parameters)"
    return {
        "regime": regime,
        "theory": label,
        "fastest_lambda_cells": top["dct_lambda_cells"],
        "fastest_growth_per_s": top["growth_per_s"],
        "oscillation_period_s": top["period_s"],
        "unstable_set_cells": [list(x) for x in dict.fromkeys(tuple(iv["lambda_cells"]) for iv in intervals)],
        "unstable_intervals": [{k: v for k, v in iv.items() if k != "kappa"} for iv in intervals],
        "fastest_mode_walls": top["walls"],
    }
