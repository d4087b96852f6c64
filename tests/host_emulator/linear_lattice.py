"""Linear lattice state matrix from docs/physics.md#equations-of-motion: the independent reference of the
stepper tests."""

import numpy as np


def linear_system(p, inertia=True):
    """State matrix of the linear lattice (linear bands, |alpha| below the psi' breakpoint), from
    docs/physics.md#equations-of-motion."""
    n = p.cells
    lap = np.diag(np.r_[1, 2 * np.ones(n - 2), 1]) - np.eye(n, k=1) - np.eye(n, k=-1)
    K = np.block([[p.ka_eff * lap, np.zeros((n, n))], [np.zeros((n, n)), p.kb_eff * lap]])
    J = np.block(
        [[(-p.k_ab - p.k2) * np.eye(n), (p.k_ab - p.sigma) * np.eye(n)], [p.k_ab * np.eye(n), -p.k_ab * np.eye(n)]]
    )
    moi = np.r_[np.full(n, p.I_a), np.full(n, p.I_b)]
    eta = np.r_[np.full(n, p.eta_alpha), np.full(n, p.eta_beta)]
    if not inertia:
        return (J - K) / eta[:, None]
    A = np.zeros((4 * n, 4 * n))
    A[: 2 * n, 2 * n :] = np.eye(2 * n)
    A[2 * n :, : 2 * n] = (J - K) / moi[:, None]
    A[2 * n :, 2 * n :] = -np.diag(eta / moi)
    return A
