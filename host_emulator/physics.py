"""The emulator's Python physics, written once: reaction law, its derivative, Gershgorin bound, cubic band law.

Every Python model imports these (params.Params.psi_prime, models/continuum.py, models/reference.py,
analysis/stability.py, the py-pde benchmark's expressions); nothing else in the Python code writes them.
The other copies, one per language, and why each exists:

* ``lib/metacell/src/control/mc_reaction.h``: the firmware's fixed-point law (the cells run it; no float);
* ``host_emulator/csrc/he_plant.c``: the compiled float plant (``he_reaction``, ``he_react_stiffness``,
  ``he_band_slope``, ``cubic``), which the lattice steppers call a billion times per sweep.

tests/host_emulator/test_physics.py checks all of them against one float reference (tests/firmware/reference.py).
Units SI: angles rad, torques N m, gains N m/rad; the band law is in N against the stretch in m.
"""

from __future__ import annotations

import numpy as np

__all__ = [
    "band_force",
    "band_slope",
    "psi_prime",
    "psi_prime_and_slope",
    "reaction",
    "reaction_jacobian",
    "reaction_gershgorin",
    "pypde_reaction",
]


# ---- cubic band law (docs/physics.md#band-torque); C: he_plant.c cubic / he_band_slope ------------------
def band_force(coef, delta):
    """Cubic fit f(delta) = c0 + c1 d + c2 d^2 + c3 d^3 [N] (floats or numpy arrays)."""
    c0, c1, c2, c3 = coef
    return c0 + delta * (c1 + delta * (c2 + delta * c3))


def band_slope(coef, delta):
    """f'(delta) = c1 + 2 c2 d + 3 c3 d^2 [N/m], the derivative of band_force."""
    _, c1, c2, c3 = coef
    return c1 + delta * (2 * c2 + delta * 3 * c3)


# ---- reaction law (docs/physics.md#reaction-torques); C: he_plant.c he_reaction; firmware: mc_reaction.h ----
#   R_a = k_ab (beta - alpha) - psi'(alpha) - sigma beta,    R_b = k_ab (alpha - beta)
#   psi'(a) = k1 (a + a*)  a < -b;   k2 a  |a| <= b;   k1 (a - a*)  a > b;    b = k1 a* / (k1 - k2)
def _law(params, name):
    """A reaction parameter as a float, or a numpy array (one value per cell, broadcast along the last axis of the
    angles) when the parameters give one value per cell (params.Params.per_cell_keys)."""
    v = getattr(params, name)
    return np.asarray(v, dtype=float) if isinstance(v, (tuple, list, np.ndarray)) else v


def psi_prime_and_slope(params, alpha):
    """psi'(alpha) (tri-linear, odd) and psi''(alpha), elementwise on a numpy array; k1 == k2 means k2 alpha.

    Per-cell parameters (arrays of one value per cell) broadcast along the last axis of alpha (the cells)."""
    k1, k2, ast = _law(params, "k1"), _law(params, "k2"), _law(params, "alpha_star")
    if np.ndim(k1) == 0 and np.ndim(k2) == 0 and np.ndim(ast) == 0:
        if k1 == k2:
            return k2 * alpha, np.full_like(alpha, k2)
        b = k1 * ast / (k1 - k2)  # breakpoint |alpha| = k1 alpha* / (k1 - k2)
    else:
        same = np.asarray(k1 == k2)
        with np.errstate(divide="ignore", invalid="ignore"):
            b = np.where(same, np.inf, k1 * ast / np.where(same, 1.0, k1 - k2))  # k1 == k2: never the outer branch
    outer = np.abs(alpha) > b
    pp = np.where(outer, k1 * (alpha - np.sign(alpha) * ast), k2 * alpha)
    return pp, np.where(outer, k1, k2) * np.ones_like(alpha)


def psi_prime(params, alpha):
    """psi'(alpha) for a float or numpy array (a float in, a float out)."""
    a = np.asarray(alpha, dtype=float)
    pp, _ = psi_prime_and_slope(params, a)
    return pp if pp.ndim else float(pp)


def reaction(params, alpha, beta):
    """(R_a, R_b) in N m for angles alpha, beta in rad (numpy arrays or floats), no actuator limit.

    Per-cell parameters broadcast along the last axis of alpha and beta (the cells)."""
    a = np.asarray(alpha, dtype=float)
    b = np.asarray(beta, dtype=float)
    pp, _ = psi_prime_and_slope(params, a)
    kab = _law(params, "k_ab")
    ra = kab * (b - a) - pp - _law(params, "sigma") * b
    rb = kab * (a - b)
    return (ra, rb) if ra.ndim else (float(ra), float(rb))


def reaction_jacobian(params, alpha=None) -> np.ndarray:
    """dR/d(alpha, beta) at alpha, N m/rad: [[-k_ab - psi''(alpha), k_ab - sigma], [k_ab, -k_ab]].

    alpha None: at rest, psi''(0) = k2 (the inner branch). Shape (2, 2) for a scalar alpha and scalar parameters,
    (2, 2, *shape) for an array alpha (one Jacobian per cell) or per-cell parameters (shape: their broadcast)."""
    kab, s = _law(params, "k_ab"), _law(params, "sigma")
    if alpha is None:
        a, slope = np.zeros(np.shape(_law(params, "k2"))), _law(params, "k2")
    else:
        a = np.asarray(alpha, dtype=float)
        _, slope = psi_prime_and_slope(params, a)
    one = np.ones(np.broadcast_shapes(np.shape(a), np.shape(slope), np.shape(kab), np.shape(s)))
    return np.array(
        [[(-kab - slope) * one, (kab - s) * one], [kab * one, -kab * one]],
        dtype=float,
    )


def reaction_gershgorin(params) -> tuple[float, float]:
    """Gershgorin row bounds (alpha row, beta row) of dR/dx over every alpha, N m/rad:
    max(|k_ab + k1|, |k_ab + k2|) + |k_ab - sigma|  and  2 |k_ab|  (psi'' takes only the values k1, k2); the
    largest over the cells for per-cell parameters. C: he_plant.c he_react_stiffness."""
    kab, k1, k2, s = (_law(params, k) for k in ("k_ab", "k1", "k2", "sigma"))
    alpha_row = np.maximum(np.abs(kab + k1), np.abs(kab + k2)) + np.abs(kab - s)
    return float(np.max(alpha_row)), float(np.max(2.0 * np.abs(kab)))


def pypde_reaction(params) -> tuple[str, str]:
    """(R_a, R_b) as py-pde expressions of the fields a, b (sympy syntax), the same law as `reaction`.

    psi' is written without branches: psi'(a) = k1 a - k1 a* clip(a/b, -1, 1), clip(u) = (|u + 1| - |u - 1|)/2.
    tests/host_emulator/test_physics.py evaluates these strings against `reaction`. Needs one value of each
    parameter for every cell (ValueError otherwise)."""
    p = params.uniform() if hasattr(params, "uniform") else params
    bk = p.k1 * p.alpha_star / (p.k1 - p.k2)
    psi = f"({p.k1!r}*a - {p.k1 * p.alpha_star!r}*(Abs(a/{bk!r} + 1) - Abs(a/{bk!r} - 1))/2)"
    return f"({p.k_ab!r}*(b - a) - {psi} - {p.sigma!r}*b)", f"({p.k_ab!r}*(a - b))"
