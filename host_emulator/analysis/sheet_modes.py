"""Linear modes of a whole lattice (chain or sheet, any topology), heterogeneous or not: the eigenproblem of the
lattice's Jacobian at rest, dense for small lattices and sparse shift-invert for large ones (docs/sheets.md).

The lattice linearised about rest (x = alpha_1..alpha_n, beta_1..beta_n in cell order; rad, N m, s)::

    I x'' + E x' = A x,      A = R - K
    R = [[diag(-k_ab_j - k2_j), diag(k_ab_j - sigma_j)], [diag(k_ab_j), diag(-k_ab_j)]]   (each cell's dR/dx)
    K = blockdiag(ka_eff L_a, kb_eff L_b)    (L = Topology.laplacian(w): bond b weighted by its stiffness factor,
                                              one set of factors per chain, in the topology's bond order)
    E = diag(eta_a,j + m, eta_b,j + m)       (m: the hil motors' back-EMF damping, theory.motor_damping)
    I = diag(I_a, I_b)

Without inertia the growth rates are the eigenvalues of E^-1 A (2n); with inertia those of the companion matrix
[[0, 1], [I^-1 A, -I^-1 E]] (4n). Neither is symmetric (the -sigma beta term is non-reciprocal), so the sparse
solver is scipy.sparse.linalg.eigs in shift-invert mode about a shift above every growth rate: it returns the
modes nearest that shift, i.e. the fastest ones (a strongly oscillatory mode far from the real axis could rank
behind a slower real one: `method="dense"` is exact). A chain gives what analysis.chain gives.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from typing import TYPE_CHECKING, Any

import numpy as np

from .stability import Theory, growth_rates_at_q

if TYPE_CHECKING:
    from ..params import Params
    from ..topology import Topology

__all__ = [
    "sheet_matrices",
    "dense_eig",
    "sheet_modes",
    "distinct_modes",
    "mode_rates",
    "dominant_wavevector",
    "DENSE_MAX_CELLS",
]

DENSE_MAX_CELLS = 100  # method="auto": dense eig up to this many cells (a 10 x 10 sheet), sparse above


def sheet_matrices(
    params: Params,
    theory: Theory | None = None,
    *,
    band_factors: np.ndarray | None = None,
    eta_factors: np.ndarray | None = None,
    topology: Topology | None = None,
    sparse: bool = False,
):
    """(A, e, i) of the module docstring: A (2n, 2n) in N m/rad (a numpy array, or scipy CSR with sparse=True), e
    and i the diagonals of E (N m s) and I (kg m^2), each (2n,).

    band_factors: (2, nbond) stiffness factors of each bond of the alpha and beta chains (topology.bonds order;
    default 1); eta_factors: (2, n) viscosity factors of each cylinder (default 1). Per-cell reaction parameters
    (Params' tuples) are in cell order."""
    import scipy.sparse as sp

    theory = theory or Theory("lattice", True, True, 0.0)
    topo = topology or params.topology
    n = topo.n
    if params.cells != n:
        raise ValueError(f"params.cells = {params.cells} but the topology has {n} cells")
    kab, sig, k2 = params.per_cell("k_ab"), params.per_cell("sigma"), params.per_cell("k2")
    nb = topo.nbond
    band = np.ones((2, nb)) if band_factors is None else np.asarray(band_factors, dtype=float)
    eta = np.ones((2, n)) if eta_factors is None else np.asarray(eta_factors, dtype=float)
    if band.shape != (2, nb) or eta.shape != (2, n):
        raise ValueError(f"band_factors must have shape (2, {nb}) and eta_factors (2, {n})")
    if nb:
        la, lb = topo.laplacian(band[0]), topo.laplacian(band[1])
    else:  # one cell: no bond
        la = lb = sp.csr_matrix((n, n))
    if sparse:
        a = sp.bmat(
            [
                [-params.ka_eff * la + sp.diags(-kab - k2), sp.diags(kab - sig)],
                [sp.diags(kab), -params.kb_eff * lb + sp.diags(-kab)],
            ],
            format="csr",
        )
    else:
        a = np.zeros((2 * n, 2 * n))
        a[:n, :n] = -params.ka_eff * la.toarray() + np.diag(-kab - k2)
        a[:n, n:] = np.diag(kab - sig)
        a[n:, :n] = np.diag(kab)
        a[n:, n:] = -params.kb_eff * lb.toarray() + np.diag(-kab)
    damp = float(theory.motor_damping)
    e = np.concatenate([params.eta_alpha * eta[0] + damp, params.eta_beta * eta[1] + damp])
    i = np.concatenate([np.full(n, params.I_a), np.full(n, params.I_b)])
    return a, e, i


def _system(a, e: np.ndarray, i: np.ndarray, inertia: bool):
    """E^-1 A, or the companion matrix with inertia (dense in, dense out; sparse in, sparse out)."""
    import scipy.sparse as sp

    if sp.issparse(a):
        if not inertia:
            return (sp.diags(1.0 / e) @ a).tocsc()
        n2 = a.shape[0]
        return sp.bmat([[None, sp.identity(n2)], [sp.diags(1.0 / i) @ a, sp.diags(-e / i)]], format="csc")
    if not inertia:
        return a / e[:, None]
    n2 = a.shape[0]
    m = np.zeros((2 * n2, 2 * n2))
    m[:n2, n2:] = np.eye(n2)
    m[n2:, :n2] = a / i[:, None]
    m[n2:, n2:] = -np.diag(e / i)
    return m


def dense_eig(a: np.ndarray, e: np.ndarray, i: np.ndarray, inertia: bool) -> tuple[np.ndarray, np.ndarray]:
    """Every eigenvalue and eigenvector of the linearised lattice, sorted Re descending (ties: +Im first)."""
    w, v = np.linalg.eig(_system(a, e, i, inertia))
    order = np.lexsort((-w.imag, -w.real))
    return w[order], v[:, order]


def _shift(params: Params, theory: Theory, e: np.ndarray) -> float:
    """A real number above every growth rate's real part (the shift of the sparse solver): the largest growth
    rate of any one cell's law over every q (which bounds a uniform lattice's) with a margin, or a Gershgorin
    bound of E^-1 R without inertia (the bands' rows sum to zero)."""
    n = params.cells
    kab, sig, k2 = params.per_cell("k_ab"), params.per_cell("sigma"), params.per_cell("k2")
    if not theory.inertia:
        row_a = (-kab - k2 + np.abs(kab - sig)) / e[:n]
        row_b = (-kab + np.abs(kab)) / e[n:]
        return float(max(row_a.max(), row_b.max(), 0.0)) * 1.05 + 1.0
    best = 0.0
    q = np.linspace(0.0, 12.0, 241)
    seen = set()
    for j in range(n):
        key = (float(kab[j]), float(sig[j]), float(k2[j]))
        if key in seen:
            continue
        seen.add(key)
        s = growth_rates_at_q(params.cell(j + 1), q, inertia=True, motor_damping=theory.motor_damping)[:, 0]
        best = max(best, float(s.real.max()))
    return 1.5 * best + 10.0


def sparse_eig(params: Params, theory: Theory, count: int, **kw: Any) -> tuple[np.ndarray, np.ndarray]:
    """The `count` (at least) eigenvalues nearest a shift above every growth rate, with their eigenvectors, sorted
    Re descending: the fastest modes of a large lattice (scipy.sparse.linalg.eigs, shift-invert)."""
    from scipy.sparse.linalg import eigs

    a, e, i = sheet_matrices(params, theory, sparse=True, **kw)
    m = _system(a, e, i, theory.inertia)
    k = min(int(count), m.shape[0] - 2)
    w, v = eigs(m, k=k, sigma=_shift(params, theory, e), which="LM", tol=1e-12, maxiter=20000)
    order = np.lexsort((-w.imag, -w.real))
    return w[order], v[:, order]


def dominant_wavevector(alpha_grid: np.ndarray, topology: Topology) -> tuple[list[float], float | None]:
    """([k_row, k_col] Cartesian rad/cell, wavelength 2 pi / |k| in cells or None) of a mode shape's largest Fourier
    component: the 2-D FFT of a periodic sheet, the 2-D cosine transform (Neumann modes) of an open one."""
    from scipy.fft import dctn

    from .sheet import _cartesian, _reduce

    g = np.asarray(alpha_grid, dtype=float)
    rows, cols = g.shape
    if topology.periodic:
        f = np.abs(np.fft.fft2(g))
        r, c = np.unravel_index(int(np.argmax(f)), f.shape)
        pr = 2 * math.pi * (r if r <= rows // 2 else r - rows) / rows
        pc = 2 * math.pi * (c if c <= cols // 2 else c - cols) / cols
    else:
        f = np.abs(dctn(g, type=2, norm="ortho"))
        r, c = np.unravel_index(int(np.argmax(f)), f.shape)
        pr, pc = math.pi * r / rows, math.pi * c / cols
    kr, kc = (float(x) for x in _cartesian(topology.kind, pr, pc))
    if topology.periodic:
        kr, kc = _reduce(topology.kind, kr, kc)
    kn = math.hypot(kr, kc)
    return [kr, kc], (2 * math.pi / kn if kn > 1e-12 else None)


def distinct_modes(w: np.ndarray, v: np.ndarray, n: int) -> Iterator[tuple[complex, np.ndarray]]:
    """(s, alpha) of each distinct mode of an eigendecomposition (eigenvalues w, Re descending; eigenvectors v's
    columns), complex-conjugate pairs once (+Im first): alpha is its eigenvector's alpha part (the first n entries)
    scaled by its largest entry, real (largest entry +1). sheet_modes' and analysis.chain's modes alike."""
    for k, s in enumerate(w):
        if s.imag < -1e-9 * max(1.0, abs(s)):
            continue  # the conjugate of a mode already listed
        vec = v[:n, k]
        ph = vec[int(np.argmax(np.abs(vec)))]
        yield s, ((vec / ph).real if abs(ph) > 0 else np.zeros(n))


def mode_rates(s: complex) -> dict:
    """A mode's first entries from its eigenvalue s: growth_per_s (Re s), imag_per_s (|Im s|), period_s
    (oscillatory) or None, kind ("stationary" or "oscillatory")."""
    osc = bool(abs(s.imag) > 1e-9 * max(1.0, abs(s)))
    return {
        "growth_per_s": float(s.real),
        "imag_per_s": float(abs(s.imag)),
        "period_s": float(2 * math.pi / abs(s.imag)) if osc else None,
        "kind": "oscillatory" if osc else "stationary",
    }


def sheet_modes(
    params: Params,
    theory: Theory | None = None,
    *,
    count: int = 6,
    method: str = "auto",
    topology: Topology | None = None,
    **factors: Any,
) -> dict:
    """The lattice's fastest linear modes (complex-conjugate pairs once, +Im first), up to `count`.

    method: "dense" (every eigenvalue, numpy), "sparse" (shift-invert, the 2 count + 4 nearest the shift) or
    "auto" (dense up to DENSE_MAX_CELLS cells). Returns {"method", "growth_per_s" (the eigenvalues computed, Re
    descending), "modes": [{growth_per_s (Re s), imag_per_s, period_s (oscillatory) or None, kind, alpha (the
    alpha part of the eigenvector, real, largest entry +1, cell order), alpha_grid ((rows, cols)), wavevector
    ([k_row, k_col] of its largest Fourier component), lambda_cells (2 pi / |k|; None: uniform)}]}.
    factors: band_factors (2, nbond), eta_factors (2, n) of sheet_matrices."""
    theory = theory or Theory("lattice", True, True, 0.0)
    topo = topology or params.topology
    n = topo.n
    if method not in ("auto", "dense", "sparse"):
        raise ValueError(f"method={method!r}: expected auto, dense or sparse")
    use_dense = method == "dense" or (method == "auto" and n <= DENSE_MAX_CELLS)
    if use_dense:
        a, e, i = sheet_matrices(params, theory, topology=topo, **factors)
        w, v = dense_eig(a, e, i, theory.inertia)
    else:
        w, v = sparse_eig(params, theory, 2 * count + 4, topology=topo, **factors)
    modes = []
    for s, alpha in distinct_modes(w, v, n):
        grid = topo.grid(alpha)
        kvec, lam = dominant_wavevector(grid, topo)
        modes.append(
            {
                **mode_rates(s),
                "alpha": alpha,
                "alpha_grid": grid,
                "wavevector": kvec,
                "lambda_cells": lam,
            }
        )
        if len(modes) >= count:
            break
    return {"method": "dense" if use_dense else "sparse", "growth_per_s": w, "modes": modes}
