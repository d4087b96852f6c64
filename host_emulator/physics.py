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
def psi_prime_and_slope(params, alpha):
    """psi'(alpha) (tri-linear, odd) and psi''(alpha), elementwise on a numpy array; k1 == k2 means k2 alpha."""
    k1, k2, ast = params.k1, params.k2, params.alpha_star
    if k1 == k2:
        return k2 * alpha, np.full_like(alpha, k2)
    b = k1 * ast / (k1 - k2)  # breakpoint |alpha| = k1 alpha* / (k1 - k2)
    outer = np.abs(alpha) > b
    pp = np.where(outer, k1 * (alpha - np.sign(alpha) * ast), k2 * alpha)
    return pp, np.where(outer, k1, k2)


def psi_prime(params, alpha):
    """psi'(alpha) for a float or numpy array (a float in, a float out)."""
    a = np.asarray(alpha, dtype=float)
    pp, _ = psi_prime_and_slope(params, a)
    return pp if pp.ndim else float(pp)


def reaction(params, alpha, beta):
    """(R_a, R_b) in N m for angles alpha, beta in rad (numpy arrays or floats), no actuator limit."""
    a = np.asarray(alpha, dtype=float)
    b = np.asarray(beta, dtype=float)
    pp, _ = psi_prime_and_slope(params, a)
    kab = params.k_ab
    ra = kab * (b - a) - pp - params.sigma * b
    rb = kab * (a - b)
    return (ra, rb) if ra.ndim else (float(ra), float(rb))


def reaction_jacobian(params, alpha=None) -> np.ndarray:
    """dR/d(alpha, beta) at alpha, N m/rad: [[-k_ab - psi''(alpha), k_ab - sigma], [k_ab, -k_ab]].

    alpha None: at rest, psi''(0) = k2 (the inner branch). Shape (2, 2) for a scalar alpha,
    (2, 2, *alpha.shape) for an array (one Jacobian per cell)."""
    if alpha is None:
        a, slope = np.asarray(0.0), params.k2
    else:
        a = np.asarray(alpha, dtype=float)
        _, slope = psi_prime_and_slope(params, a)
    kab, s = params.k_ab, params.sigma
    one = np.ones_like(a)
    return np.array([[-kab - slope, (kab - s) * one], [kab * one, -kab * one]], dtype=float)


def reaction_gershgorin(params) -> tuple[float, float]:
    """Gershgorin row bounds (alpha row, beta row) of dR/dx over every alpha, N m/rad:
    max(|k_ab + k1|, |k_ab + k2|) + |k_ab - sigma|  and  2 |k_ab|  (psi'' takes only the values k1, k2).
    C: he_plant.c he_react_stiffness."""
    kab = params.k_ab
    alpha_row = max(abs(kab + params.k1), abs(kab + params.k2)) + abs(kab - params.sigma)
    return alpha_row, 2.0 * abs(kab)


def pypde_reaction(params) -> tuple[str, str]:
    """(R_a, R_b) as py-pde expressions of the fields a, b (sympy syntax), the same law as `reaction`.

    psi' is written without branches: psi'(a) = k1 a - k1 a* clip(a/b, -1, 1), clip(u) = (|u + 1| - |u - 1|)/2.
    tests/host_emulator/test_physics.py evaluates these strings against `reaction`."""
    p = params
    bk = p.k1 * p.alpha_star / (p.k1 - p.k2)
    psi = f"({p.k1!r}*a - {p.k1 * p.alpha_star!r}*(Abs(a/{bk!r} + 1) - Abs(a/{bk!r} - 1))/2)"
    return f"({p.k_ab!r}*(b - a) - {psi} - {p.sigma!r}*b)", f"({p.k_ab!r}*(a - b))"
