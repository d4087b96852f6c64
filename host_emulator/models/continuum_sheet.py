"""Continuum model on a square sheet: the PDE of models/continuum.py on a 2-D finite-volume grid, stepped by ETDRK4
on the grid Laplacian's exact spectral diagonalisation (FFT or DCT) or by scipy's BDF with the sparse Jacobian.

Grid: cell (row r, col c) (1-based, cell = (r - 1) cols + c) is the unit square x in [c - 1, c], y in [r - 1, r],
split into M x M finite volumes of side h = 1/M (M = points_per_cell); volume (i, j) (row i of R = rows M, column j
of C = cols M) has its centre at x = (j + 1/2) h, y = (i + 1/2) h. The Laplacian is the 5-point one,

    (L u)_ij = (u_i-1,j + u_i+1,j + u_i,j-1 + u_i,j+1 - 4 u_ij) / h^2,

with zero flux through the sheet's edges (ghost = edge value, boundary "open") or wrapped both ways ("periodic").
Each volume follows its cell's reaction law; a torque T on a cell is the density T per unit area over the cell's
square. Output: bilinear interpolation to the cell centres (for M even the mean of the 4 central volumes, for M
odd the central one), (samples, n) in cell order.

ETDRK4 (Cox & Matthews 2002, in the form of Kassam & Trefethen 2005): the state's linear part

    d/dt (a, b) = E^-1 (J_ref - q K) (a, b)        (q the grid Laplacian's eigenvalue, K = diag(ka_eff, kb_eff))

is integrated exactly mode by mode (2 x 2 matrix functions of each distinct q, in closed form), the rest
N = E^-1 (R(a, b) - J_ref (a, b)) + P/E explicitly; J_ref is the reaction Jacobian at rest (psi'' = k2; the mean
law for per-cell parameters), so with uniform parameters N is nonzero only where |alpha| passes the breakpoint of
psi'. The zero-flux 5-point Laplacian is diagonal in the DCT-II basis cos(pi k (i + 1/2) / R), the periodic one in
the Fourier basis: the linear part is the same semi-discrete operator the BDF path factorises, not a spectral
approximation of it. Step size: step doubling (one step of h against two of h/2, local error (u2 - u1)/15; an
embedded second-order estimate was tried and took 5x more steps), the step accepted when max over the grid of
|error| / (atol + rtol |y|) <= 1; steps land on every output time and perturbation switch.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from collections.abc import Callable, Sequence
from types import SimpleNamespace

import numpy as np
import scipy.fft as sfft
import scipy.sparse as sp

from ..params import REACTION_KEYS, Params
from ..physics import reaction, reaction_jacobian
from ..topology import Topology

__all__ = ["SheetGrid", "simulate_sheet", "matrix_phi", "SHEET_METHODS"]

SHEET_METHODS = ("auto", "etdrk4", "BDF", "Radau", "LSODA")


class SheetGrid:
    """The finite-volume grid of a square sheet: sizes, Laplacian (sparse and spectral), cell <-> volume maps."""

    def __init__(self, topology: Topology, m: int):
        self.topology = topology
        self.rows, self.cols, self.m = topology.rows, topology.cols, int(m)
        self.R, self.C = self.rows * self.m, self.cols * self.m
        self.h = 1.0 / self.m
        self.periodic = topology.periodic
        self.size = self.R * self.C

    # ---- geometry -------------------------------------------------------------------------------------
    def coords(self) -> tuple[np.ndarray, np.ndarray]:
        """(x, y) of the volume centres, each (R, C): x along a row, y down the rows, in cells."""
        y, x = np.meshgrid((np.arange(self.R) + 0.5) * self.h, (np.arange(self.C) + 0.5) * self.h, indexing="ij")
        return x, y

    def expand(self, per_cell: np.ndarray) -> np.ndarray:
        """(n,) values in cell order -> (R, C), each cell's value on its M x M volumes."""
        g = np.asarray(per_cell, dtype=float).reshape(self.rows, self.cols)
        return np.repeat(np.repeat(g, self.m, axis=0), self.m, axis=1)

    def cell_block(self, cell: int) -> tuple[slice, slice]:
        r, c = self.topology.row_col(cell)
        return slice((r - 1) * self.m, r * self.m), slice((c - 1) * self.m, c * self.m)

    def _centre_1d(self, cells: int) -> np.ndarray:
        """(cells, cells M) linear interpolation to the cell centres (the 1-D model's own sampling rule)."""
        n = cells * self.m
        x = (np.arange(n) + 0.5) * self.h
        xc = np.arange(cells) + 0.5
        eye = np.eye(n)
        return np.stack([np.interp(xc, x, eye[j]) for j in range(n)], axis=1)

    def sampler(self) -> Callable[[np.ndarray], np.ndarray]:
        """u (..., R, C) -> (..., n): bilinear interpolation to the cell centres, cell order."""
        sr, sc = self._centre_1d(self.rows), self._centre_1d(self.cols)

        def sample(u: np.ndarray) -> np.ndarray:
            v = sr @ u @ sc.T
            return v.reshape(*v.shape[:-2], self.rows * self.cols)

        return sample

    # ---- operators ------------------------------------------------------------------------------------
    def _lap_1d(self, n: int):
        main = np.full(n, -2.0)
        off = np.ones(n - 1)
        if not self.periodic:
            main[0] += 1.0
            main[-1] += 1.0
            if n == 1:
                main[0] = 0.0
        a = sp.diags([off, main, off], [-1, 0, 1], shape=(n, n), format="lil")
        if self.periodic:
            a[0, n - 1] += 1.0
            a[n - 1, 0] += 1.0
        return a.tocsr() / (self.h * self.h)

    def laplacian(self):
        """The 5-point Laplacian on the flattened (row-major) grid, sparse (R C x R C)."""
        return (
            sp.kron(sp.identity(self.R), self._lap_1d(self.C)) + sp.kron(self._lap_1d(self.R), sp.identity(self.C))
        ).tocsr()

    def spectral_q(self) -> np.ndarray:
        """-eigenvalue of the Laplacian of each spectral coefficient, laid out as the transform's output."""
        h2 = self.h * self.h
        if self.periodic:
            kr = np.arange(self.R)
            kc = np.arange(self.C // 2 + 1)
            sr, sc = np.sin(np.pi * kr / self.R) ** 2, np.sin(np.pi * kc / self.C) ** 2
        else:
            sr = np.sin(np.pi * np.arange(self.R) / (2 * self.R)) ** 2
            sc = np.sin(np.pi * np.arange(self.C) / (2 * self.C)) ** 2
        return (4.0 / h2) * (sr[:, None] + sc[None, :])

    def forward(self, u: np.ndarray) -> np.ndarray:
        if self.periodic:
            return sfft.rfft2(u, norm="ortho")
        return sfft.dctn(u, type=2, axes=(-2, -1), norm="ortho")

    def inverse(self, u: np.ndarray) -> np.ndarray:
        if self.periodic:
            return sfft.irfft2(u, s=(self.R, self.C), norm="ortho")
        return sfft.idctn(u, type=2, axes=(-2, -1), norm="ortho")


# ---------------------------------------------------------------- phi functions of 2 x 2 matrices
def _phis(z: np.ndarray, kmax: int) -> list[np.ndarray]:
    """[phi_0(z), ..., phi_kmax(z)] elementwise (complex z): phi_0 = exp, phi_k(z) = (phi_k-1(z) - 1/(k-1)!) / z;
    Taylor series (sum_j z^j / (j + k)!) where |z| < 1 (the recurrence cancels there), the recurrence elsewhere
    (|z| >= 1: an absolute error never grows through it)."""
    z0 = np.asarray(z, dtype=complex)
    z = z0.reshape(-1)
    small = np.abs(z) < 1.0
    zb = np.where(small, 1.0, z)
    zs = z[small]
    out = [np.exp(z)]
    for k in range(1, kmax + 1):
        val = (out[-1] - 1.0 / math.factorial(k - 1)) / zb
        if zs.size:
            ser = np.full_like(zs, 1.0 / math.factorial(k + 19))
            for j in range(18, -1, -1):  # Horner; |z| < 1: the first omitted term is below 1/(20 + k)! < 1e-18
                ser = ser * zs + 1.0 / math.factorial(k + j)
            val[small] = ser
        out.append(val)
    return [o.reshape(z0.shape) for o in out]


# g(z) = sum_k c_k phi_k(z): the ETDRK4 coefficients, each as {k: c_k}
_COMBOS = {
    "exp": {0: 1.0},
    "phi1": {1: 1.0},
    "phi2": {2: 1.0},
    "f1": {1: 1.0, 2: -3.0, 3: 4.0},
    "f2": {2: 1.0, 3: -2.0},
    "f3": {2: -1.0, 3: 4.0},
}


def _derivs(phis: list[np.ndarray], combo: dict[int, float], order: int) -> np.ndarray:
    """The order-th derivative of sum_k c_k phi_k, by phi_k' = phi_k - k phi_k+1 (so phi_k^(n) needs up to k + n)."""
    total = np.zeros_like(phis[0])
    for k, c in combo.items():
        # d^n/dz^n phi_k = sum_i (-1)^i C(n, i) k (k+1) ... (k+i-1) phi_{k+i}
        for i in range(order + 1):
            rising = math.prod(range(k, k + i)) if i else 1
            total = total + c * (-1) ** i * math.comb(order, i) * rising * phis[k + i]
    return total


def matrix_phi(a: np.ndarray, combos: Sequence[str]) -> dict[str, np.ndarray]:
    """g(A) for each name in combos (keys of _COMBOS) and each real 2 x 2 matrix of a (..., 2, 2), in closed form:
    g(A) = (g(mu + d) + g(mu - d))/2 I + (g(mu + d) - g(mu - d))/(2 d) (A - mu I), mu = tr A / 2,
    d = sqrt(mu^2 - det A) (complex when A rotates); where |d| < 1e-3 the divided differences are replaced by
    their Taylor series in d (a double eigenvalue is a limit, not a special case)."""
    a = np.asarray(a, dtype=float)
    mu = 0.5 * (a[..., 0, 0] + a[..., 1, 1])
    # mu^2 - det = ((a00 - a11)/2)^2 + a01 a10 (no cancellation between two large squares)
    d = np.sqrt((0.5 * (a[..., 0, 0] - a[..., 1, 1])) ** 2 + a[..., 0, 1] * a[..., 1, 0] + 0j)
    near = np.abs(d) < 1e-3
    dd = np.where(near, 1.0, d)
    kmax = max(max(_COMBOS[c]) for c in combos)
    pp, pm = _phis(mu + dd, kmax), _phis(mu - dd, kmax)
    pc = _phis(mu + 0j, kmax + 3) if np.any(near) else None  # up to phi_(k+3) for the third derivative
    eye = np.eye(2)
    am = a - mu[..., None, None] * eye
    out = {}
    for name in combos:
        combo = _COMBOS[name]
        gp = np.sum([c * pp[k] for k, c in combo.items()], axis=0)
        gm = np.sum([c * pm[k] for k, c in combo.items()], axis=0)
        s0 = 0.5 * (gp + gm)
        s1 = (gp - gm) / (2.0 * dd)
        if pc is not None:
            d2 = d * d
            t0 = _derivs(pc, combo, 0) + _derivs(pc, combo, 2) * d2 / 2
            t1 = _derivs(pc, combo, 1) + _derivs(pc, combo, 3) * d2 / 6
            s0, s1 = np.where(near, t0, s0), np.where(near, t1, s1)
        out[name] = (s0.real[..., None, None] * eye + s1.real[..., None, None] * am).astype(float)
    return out


# ---------------------------------------------------------------- ETDRK4 with step doubling
class _Etdrk4:
    """ETDRK4 on the spectral coefficients (2, *spec) of (alpha, beta); see the module docstring."""

    def __init__(
        self, grid: SheetGrid, lin: np.ndarray, diff: tuple[float, float], nonlinear, rtol: float, atol: float
    ):
        self.grid, self.lin, self.nonlinear = grid, lin, nonlinear
        self.rtol, self.atol = rtol, atol
        q = grid.spectral_q()
        self.uq, inv = np.unique(q, return_inverse=True)
        self.inv = inv.reshape(q.shape)
        self.diff = diff
        self._cache: OrderedDict[float, dict[str, np.ndarray]] = OrderedDict()
        self.forcing_hat = np.zeros((2, *q.shape))
        self.steps = self.rejected = self.evals = 0
        self.beta_free = False  # set by the caller: N_beta = 0 (uniform law, no push on beta)

    def coefficients(self, h: float) -> dict[str, np.ndarray]:
        """The step's matrices, each (2, 2, *spec): e^{Lh}, e^{Lh/2}, Q = h/2 phi1(Lh/2), f1, f2, f3."""
        got = self._cache.get(h)
        if got is not None:
            self._cache.move_to_end(h)
            return got
        a = np.broadcast_to(self.lin, (self.uq.size, 2, 2)).copy()
        a[:, 0, 0] -= self.uq * self.diff[0]
        a[:, 1, 1] -= self.uq * self.diff[1]
        full = matrix_phi(a * h, ("exp", "f1", "f2", "f3"))
        half = matrix_phi(a * (0.5 * h), ("exp", "phi1"))
        mats = {
            "E": full["exp"],
            "E2": half["exp"],
            "Q": half["phi1"] * (0.5 * h),
            "f1": full["f1"] * h,
            "f2": full["f2"] * (2.0 * h),  # the scheme's 2 f2 folded in
            "f3": full["f3"] * h,
        }
        got = {k: np.moveaxis(v[self.inv], (-2, -1), (0, 1)).copy() for k, v in mats.items()}
        self._cache[h] = got
        if len(self._cache) > max(6, int(2e8 // (24 * 16 * self.inv.size))):  # up to ~200 MB of coefficients
            self._cache.popitem(last=False)
        return got

    @staticmethod
    def _apply(m: np.ndarray, v: np.ndarray) -> np.ndarray:
        return m[:, 0] * v[0] + m[:, 1] * v[1]

    def _apply_n(self, m: np.ndarray, n: np.ndarray) -> np.ndarray:
        """m applied to a nonlinear term (its beta part is zero when beta_free)."""
        return m[:, 0] * n[0] if self.beta_free else m[:, 0] * n[0] + m[:, 1] * n[1]

    def nhat(self, v: np.ndarray, real: np.ndarray | None = None) -> np.ndarray:
        """N of the state with spectral coefficients v (its real-space values when known), transformed."""
        self.evals += 1
        return self.nonlinear(v, real) + self.forcing_hat

    def step(self, v: np.ndarray, nv: np.ndarray, h: float) -> np.ndarray:
        """One ETDRK4 step of h from v, N(v) = nv given."""
        c = self.coefficients(h)
        ap, an, e2, q = self._apply, self._apply_n, c["E2"], c["Q"]
        e2v = ap(e2, v)
        a = e2v + an(q, nv)
        na = self.nhat(a)
        b = e2v + an(q, na)
        nb = self.nhat(b)
        cc = ap(e2, a) + an(q, 2.0 * nb - nv)
        nc = self.nhat(cc)
        return ap(c["E"], v) + an(c["f1"], nv) + an(c["f2"], na + nb) + an(c["f3"], nc)

    def advance(self, v: np.ndarray, y: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray, float]:
        """One step-doubled step of h from v (real values y): (v2, y2, error ratio); accepted when the ratio <= 1."""
        nv = self.nhat(v, y)
        u1 = self.step(v, nv, h)
        vh = self.step(v, nv, 0.5 * h)
        u2 = self.step(vh, self.nhat(vh), 0.5 * h)
        g = self.grid
        y2 = g.inverse(u2)
        err = g.inverse(u2 - u1) / 15.0
        scale = self.atol + self.rtol * np.maximum(np.abs(y), np.abs(y2))
        with np.errstate(invalid="ignore", over="ignore"):
            ratio = float(np.max(np.abs(err) / scale))
        return u2, y2, ratio if math.isfinite(ratio) else math.inf


# ---------------------------------------------------------------- the sheet's run
def _law_of(params: Params, grid: SheetGrid):
    """The reaction law per volume (flattened R C arrays) when some parameter is per cell, else params itself."""
    if not params.per_cell_keys:
        return params
    return SimpleNamespace(**{k: grid.expand(params.per_cell(k)).ravel() for k in REACTION_KEYS})


def resolve_method(params: Params, method: str) -> str:
    """'auto' -> 'etdrk4' (the spectral exponential integrator); any other name as given (ValueError if unknown)."""
    if method not in SHEET_METHODS:
        raise ValueError(f"method={method!r}: a sheet's continuum takes one of {', '.join(SHEET_METHODS)}")
    return "etdrk4" if method == "auto" else method


def simulate_sheet(
    params: Params,
    pert: list[dict],
    t_out: np.ndarray,
    cuts: list[float],
    *,
    points_per_cell: int,
    rtol: float,
    atol: float,
    initial: Callable | None,
    max_angle_rad: float,
    method: str,
) -> tuple[np.ndarray, np.ndarray]:
    """(alpha, beta), each (len(t_out), n) at the cell centres, of the sheet params.topology (validated input:
    models/continuum.simulate_continuum checks it and computes t_out and the segment cuts)."""
    from .continuum import ContinuumError, _check_state

    topo = params.topology
    grid = SheetGrid(topo, points_per_cell)
    method = resolve_method(params, method)
    R, C = grid.R, grid.C
    ea, eb = params.eta_alpha, params.eta_beta
    law = _law_of(params, grid)
    sample = grid.sampler()
    y0 = np.zeros((2, R, C))
    if initial is not None:
        x, yy = grid.coords()
        a0, b0 = initial(x, yy)
        y0[0] = np.broadcast_to(np.asarray(a0, dtype=float), (R, C))
        y0[1] = np.broadcast_to(np.asarray(b0, dtype=float), (R, C))
        if not np.all(np.isfinite(y0)):
            raise ValueError("initial state is not finite")

    def forcing(t_mid: float) -> np.ndarray:
        f = np.zeros((2, R, C))
        for p in pert:
            if p["start_s"] <= t_mid < p["start_s"] + p["duration_s"]:
                rs, cs = grid.cell_block(p["cell"])
                ch = 0 if p["chain"] == "alpha" else 1
                f[ch, rs, cs] += p["torque_Nm"] / (ea if ch == 0 else eb)
        return f

    alpha = np.full((len(t_out), topo.n), np.nan)
    beta = np.full_like(alpha, np.nan)
    alpha[0], beta[0] = sample(y0[0]), sample(y0[1])

    def check(y: np.ndarray, t0: float, t1: float) -> None:
        _check_state(y, t0, t1, max_angle_rad)

    if method == "etdrk4":
        _run_etd(params, grid, law, y0, forcing, t_out, cuts, alpha, beta, rtol, atol, check)
    else:
        _run_scipy(params, grid, law, y0, forcing, t_out, cuts, alpha, beta, rtol, atol, check, method)
    if not np.all(np.isfinite(alpha)):
        raise ContinuumError("internal error: some output times were not reached by the integration")
    return alpha, beta


def psi_outer(params) -> tuple[float, float]:
    """(k1 - k2, b) with psi'(a) - k2 a = (k1 - k2) (a - clip(a, -b, b)), b = k1 alpha* / (k1 - k2) the
    breakpoint of physics.psi_prime (k1 == k2: (0, inf)); tests check it against physics.reaction."""
    k1, k2, ast = float(params.k1), float(params.k2), float(params.alpha_star)
    if k1 == k2:
        return 0.0, math.inf
    return k1 - k2, k1 * ast / (k1 - k2)


def _steps_for(x: float) -> int:
    """The number of equal steps for a distance of x wanted steps: ceil(x) if at most 8, else rounded up to 4, 5, 6
    or 8 times a power of 2 (so the step sizes, and their cached coefficients, repeat across output intervals)."""
    n = max(1, math.ceil(x - 1e-9))
    if n <= 8:
        return n
    p = 2 ** (n.bit_length() - 3)  # n in [4p, 8p)
    return next(k * p for k in (4, 5, 6, 8) if k * p >= n)


def _run_etd(params, grid, law, y0, forcing, t_out, cuts, alpha, beta, rtol, atol, check) -> None:
    from .continuum import ContinuumError

    ea, eb = params.eta_alpha, params.eta_beta
    eta = np.array([ea, eb])
    uniform = not params.heterogeneous
    ref = (
        params.uniform()
        if uniform
        else SimpleNamespace(**{k: float(np.mean(params.per_cell(k))) for k in REACTION_KEYS})
    )
    lin = reaction_jacobian(ref) / eta[:, None]  # E^-1 J_ref, psi'' = k2
    sample = grid.sampler()
    shape = grid.forward(np.zeros((grid.R, grid.C))).shape
    zero = np.zeros(shape)

    if uniform:
        gain, brk = psi_outer(ref)
        gain /= -ea

        def nonlinear(v, real):
            a = grid.inverse(v[0]) if real is None else real[0]
            na = gain * (a - np.clip(a, -brk, brk))  # E^-1 (R - J_ref x): zero on psi's inner branch
            return np.stack([grid.forward(na) if np.any(na) else zero, zero])
    else:
        flat = (grid.R, grid.C)

        def nonlinear(v, real):
            a, b = grid.inverse(v) if real is None else real
            ra, rb = reaction(law, a.ravel(), b.ravel())
            na = ra.reshape(flat) / ea - lin[0, 0] * a - lin[0, 1] * b
            nb = rb.reshape(flat) / eb - lin[1, 0] * a - lin[1, 1] * b
            return grid.forward(np.stack([na, nb]))

    etd = _Etdrk4(grid, lin, (params.ka_eff / ea, params.kb_eff / eb), nonlinear, rtol, atol)
    y = y0.copy()
    v = grid.forward(y)
    h_want = min(1e-3, t_out[1] - t_out[0] if len(t_out) > 1 else cuts[-1])
    just_rejected = False
    for t0, t1 in zip(cuts[:-1], cuts[1:]):
        f = forcing(0.5 * (t0 + t1))
        etd.forcing_hat = grid.forward(f)
        etd.beta_free = uniform and not np.any(f[1])
        sel = np.nonzero((t_out > t0) & (t_out <= t1))[0]
        targets = [float(t_out[i]) for i in sel]
        if not targets or targets[-1] != t1:
            targets.append(t1)
        t = t0
        for tau in targets:
            h = 0.0  # the step is chosen afresh for each target, then kept while the controller is content
            while t < tau:
                r = tau - t
                if h == 0.0 or h > r * (1 + 1e-9):
                    h = float(f"{r / _steps_for(r / h_want):.12g}")
                v2, y2, ratio = etd.advance(v, y, h)
                if ratio <= 1.0:
                    etd.steps += 1
                    v, y = v2, y2
                    t = tau if tau - (t + h) < 1e-9 * h else t + h
                    check(y, t0, t1)
                    grow = 0.9 * (ratio + 1e-12) ** -0.2
                    # a dead band (the step and its cached coefficients stay while they work), at most x2 (psi's
                    # kink makes the error jump when a step starts crossing it), none right after a rejection
                    if grow > 1.5 and not just_rejected:
                        h_want = h * min(2.0, grow)
                        h = 0.0
                    just_rejected = False
                else:
                    etd.rejected += 1
                    just_rejected = True
                    h_want = h * max(0.1, 0.9 * ratio**-0.2) if math.isfinite(ratio) else 0.1 * h
                    h = 0.0
                    if h_want < 1e-12 * max(1.0, t):
                        raise ContinuumError(
                            f"continuum step size underflow at t = {t:.6g} s (error ratio {ratio:.3g})"
                        )
            i = np.nonzero(t_out == tau)[0]
            if i.size:
                alpha[i[0]], beta[i[0]] = sample(y[0]), sample(y[1])


def _run_scipy(params, grid, law, y0, forcing, t_out, cuts, alpha, beta, rtol, atol, check, method) -> None:
    from .continuum import _rhs_and_jac, _solve_cut

    n = grid.size
    ea, eb = params.eta_alpha, params.eta_beta
    lap = grid.laplacian()
    da = (params.ka_eff / ea) * lap
    db = (params.kb_eff / eb) * lap
    make_rhs, jac = _rhs_and_jac(law, n, da, db, ea, eb)  # the chain's system, on the sheet's grid
    sample = grid.sampler()
    shape2 = (grid.R, grid.C)

    y = y0.reshape(2 * n)
    for t0, t1 in zip(cuts[:-1], cuts[1:]):
        f = forcing(0.5 * (t0 + t1))
        sel, sol = _solve_cut(make_rhs(f[0].ravel(), f[1].ravel()), jac, y, t0, t1, t_out, method, rtol, atol)
        check(sol.y, t0, t1)
        for k, i in enumerate(sel):
            alpha[i] = sample(sol.y[:n, k].reshape(shape2))
            beta[i] = sample(sol.y[n:, k].reshape(shape2))
        y = sol.y[:, -1]
