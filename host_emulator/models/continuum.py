"""Continuum model: the reaction-diffusion PDE of docs/physics.md#linear-stability (inertia dropped, full non-linear
psi') on a 1-D grid (a chain, or a ring), or on a square sheet (models/continuum_sheet.py).

Equations (x in lattice units, i.e. cells, so k a^2 d^2/dx^2 with x = a * xbar becomes k d^2/dxbar^2)::

    eta_a alpha_t = ka_eff alpha_xx + R_a(alpha, beta) + P_a(x, t)
    eta_b beta_t  = kb_eff beta_xx  + R_b(alpha, beta) + P_b(x, t)
    R_a = k_ab (beta - alpha) - psi'(alpha) - sigma beta,     R_b = k_ab (alpha - beta)

on x in [0, N] (cell j occupies [j-1, j], its centre at j - 1/2) with free ends alpha_x = beta_x = 0.

Discretisation (method of lines, finite volumes of width h = 1/M, M = points_per_cell, centres
x_i = (i + 1/2) h)::

    (L u)_i = (u_{i-1} - 2 u_i + u_{i+1}) / h^2,  ghost u_{-1} = u_0, u_{n} = u_{n-1}   (zero flux)

so that sum_i h (L u)_i = 0 exactly (a pure-diffusion run conserves sum_i h eta u_i). A perturbing torque
T (N m) on cylinder j is a torque density T per unit x over [j-1, j]; its integral over the cell is T,
matching the lattice where cylinder j spans one unit of x. Time stepping: scipy's stiff BDF with the
analytic sparse Jacobian, restarted at every switch-on/off of a perturbation so no pulse is stepped over.
Output is linearly interpolated to the cell centres. A ring (Params.boundary "periodic") wraps the grid
(u_{-1} = u_{n-1}, u_n = u_0). A sheet (Params.topology.is_sheet) is the same PDE with the 2-D Laplacian:
models/continuum_sheet.py.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from types import SimpleNamespace

import numpy as np
import scipy.sparse as sp
from scipy.integrate import solve_ivp

from ..params import REACTION_KEYS, Params
from ..physics import reaction, reaction_jacobian

__all__ = ["simulate_continuum", "ContinuumError", "validate_perturbations"]

_PERT_KEYS = {"cell", "chain", "torque_Nm", "start_s", "duration_s"}


class ContinuumError(RuntimeError):
    """The continuum integration failed or diverged; the message names the cause and the time."""


def validate_perturbations(perturbations: Sequence[dict] | None, cells: int) -> list[dict]:
    """Check a perturbation list (clear ValueError naming the entry and field); returns normalised copies."""
    out = []
    for n, p in enumerate(perturbations or []):
        where = f"perturbation #{n + 1}"
        if not isinstance(p, dict):
            raise ValueError(f"{where}: expected a table/dict, got {type(p).__name__}")
        missing = _PERT_KEYS - set(p)
        extra = set(p) - _PERT_KEYS
        if missing or extra:
            raise ValueError(
                f"{where}: missing {sorted(missing)} unknown {sorted(extra)}; keys are {sorted(_PERT_KEYS)}"
            )
        cell = p["cell"]
        if isinstance(cell, bool) or not isinstance(cell, (int, np.integer)) or not 1 <= cell <= cells:
            raise ValueError(f"{where}: cell={cell!r} must be an integer in 1..{cells}")
        if p["chain"] not in ("alpha", "beta"):
            raise ValueError(f"{where}: chain={p['chain']!r} must be 'alpha' or 'beta'")
        vals = {}
        for k in ("torque_Nm", "start_s", "duration_s"):
            try:
                vals[k] = float(p[k])
            except (TypeError, ValueError):
                raise ValueError(f"{where}: {k}={p[k]!r} is not a number") from None
            if not math.isfinite(vals[k]):
                raise ValueError(f"{where}: {k}={p[k]!r} must be finite")
        if vals["start_s"] < 0 or vals["duration_s"] <= 0:
            raise ValueError(f"{where}: need start_s >= 0 and duration_s > 0")
        out.append({"cell": int(cell), "chain": p["chain"], **vals})
    return out


def _laplacian(n, h):
    """Zero-flux second difference (sparse, n x n)."""
    main = np.full(n, -2.0)
    main[0] = main[-1] = -1.0
    if n == 1:
        main[0] = 0.0
    off = np.ones(n - 1)
    return sp.diags([off, main, off], [-1, 0, 1], shape=(n, n), format="csr") / (h * h)


def _face_factors(band_row, cells: int, m: int) -> np.ndarray:
    """Stiffness factor of each of the n - 1 inner faces (face i between points i and i + 1, at x = (i + 1) / m):
    the factor of the bond nearest to it (bond b joins cells b + 1 and b + 2, at x = b + 1)."""
    if cells < 2:
        return np.ones(cells * m - 1)
    xf = np.arange(1, cells * m) / m
    b = np.clip(np.floor(xf + 0.5).astype(int) - 1, 0, cells - 2)
    return np.asarray(band_row, dtype=float)[b]


def _laplacian_weighted(n, h, w):
    """Zero-flux second difference with face weights w (n - 1): (L u)_i = sum over i's faces of w (u_nb - u_i) / h^2;
    all weights 1 is _laplacian."""
    main = np.zeros(n)
    main[:-1] -= w
    main[1:] -= w
    return sp.diags([w, main, w], [-1, 0, 1], shape=(n, n), format="csr") / (h * h)


def _laplacian_ring(n, h):
    """Periodic second difference (a ring: point n - 1 next to point 0), sparse n x n."""
    if n < 3:
        raise ValueError(f"a ring's continuum needs at least 3 grid points (got {n})")
    lap = _laplacian(n, h).tolil()
    lap[0, 0] = lap[n - 1, n - 1] = -2.0 / (h * h)
    lap[0, n - 1] = lap[n - 1, 0] = 1.0 / (h * h)
    return lap.tocsr()


def _output_times(t_end_s: float, dt_out_s: float, pert: list[dict]) -> tuple[np.ndarray, list[float]]:
    """Output times (0 to t_end_s every dt_out_s, t_end_s exactly) and segment boundaries (perturbation
    switch-on/off)."""
    n_out = int(math.floor(t_end_s / dt_out_s + 1e-9)) + 1
    t_out = np.arange(n_out) * dt_out_s
    t_out = np.append(t_out[t_out < t_end_s * (1.0 - 1e-9)], t_end_s)  # t_end exactly, never beyond
    edges = {0.0, t_end_s}
    for p in pert:
        for tb in (p["start_s"], p["start_s"] + p["duration_s"]):
            if 0.0 < tb < t_end_s:
                edges.add(tb)
    return t_out, sorted(edges)


def _sheet(params, cells, t_end_s, dt_out_s, pert, m, rtol, atol, initial, max_angle_rad, method, spread):
    """simulate_continuum on a square sheet (models/continuum_sheet.py)."""
    from .continuum_sheet import simulate_sheet

    topo = params.topology
    if topo.kind != "square":
        raise ValueError(
            f"the continuum model has no {topo.kind} sheet: its Laplacian is isotropic, so it solves square grids only"
        )
    if cells != topo.n:
        raise ValueError(f"cells={cells} but the sheet {list(topo.shape)} has {topo.n} cells")
    if spread is not None:
        raise ValueError("the noise model's band and viscosity spreads are not mapped onto a sheet's continuum")
    t_out, cuts = _output_times(t_end_s, dt_out_s, pert)
    alpha, beta = simulate_sheet(
        params,
        pert,
        t_out,
        cuts,
        points_per_cell=int(m),
        rtol=rtol,
        atol=atol,
        initial=initial,
        max_angle_rad=max_angle_rad,
        method=method,
    )
    return t_out, alpha, beta


def _rhs_and_jac(law, n, da, db, ea, eb):
    """(make_rhs, jac) of the method-of-lines system y = (alpha, beta) on n grid points (a chain's or a sheet's):
    make_rhs(fa, fb) the right-hand side with the forcing fa, fb (torque density / eta), jac its sparse Jacobian;
    da, db: the diffusion operators k L / eta; ea, eb: eta (scalars or per point); law: the reaction parameters."""

    def diag(v):
        return sp.diags(np.broadcast_to(np.asarray(v, dtype=float), (n,)), format="csr")

    j0 = reaction_jacobian(law)  # dR/d(alpha, beta); only dR_a/dalpha depends on the state
    c_ab = diag(j0[0, 1] / ea)  # d(alpha_t)/d(beta)
    c_ba = diag(j0[1, 0] / eb)  # d(beta_t)/d(alpha)
    jbb = db + diag(j0[1, 1] / eb)

    def make_rhs(fa, fb):
        def rhs(_t, y):
            a, b = y[:n], y[n:]
            ra, rb = reaction(law, a, b)  # physics.py: the one Python copy of the law
            # eta_a a_t = k_a L a + R_a(a, b) + P_a ;  eta_b b_t = k_b L b + R_b(a, b) + P_b
            at = da @ a + ra / ea + fa
            bt = db @ b + rb / eb + fb
            return np.concatenate([at, bt])

        return rhs

    def jac(_t, y):
        jaa = da + sp.diags(reaction_jacobian(law, y[:n])[0, 0] / ea)  # dR_a/dalpha = -k_ab - psi''(alpha)
        return sp.bmat([[jaa, c_ab], [c_ba, jbb]], format="csc")

    return make_rhs, jac


def _solve_cut(rhs, jac, y, t0, t1, t_out, method, rtol, atol):
    """(sel, sol): scipy's solve_ivp from state y over one segment [t0, t1] of the forcing; sel the indices of the
    output times t_out in (t0, t1], sol.y's columns the states at them (then at t1 if it is none of them).
    ContinuumError if the solver fails."""
    sel = np.nonzero((t_out > t0) & (t_out <= t1))[0]
    sol = solve_ivp(
        rhs,
        (t0, t1),
        y,
        method=method,
        jac=jac,
        rtol=rtol,
        atol=atol,
        t_eval=np.append(t_out[sel], t1) if sel.size == 0 or t_out[sel[-1]] != t1 else t_out[sel],
    )
    if not sol.success:
        raise ContinuumError(f"continuum solver failed at t = {sol.t[-1]:.6g} s: {sol.message}")
    return sel, sol


def _check_state(y: np.ndarray, t0: float, t1: float, max_angle_rad: float) -> None:
    """ContinuumError when the states y of the segment [t0, t1] are not finite or an angle exceeds max_angle_rad."""
    if not np.all(np.isfinite(y)):
        raise ContinuumError(f"continuum state became non-finite in [{t0:.6g}, {t1:.6g}] s")
    peak = float(np.max(np.abs(y)))
    if peak > max_angle_rad:
        raise ContinuumError(
            f"continuum state diverged: |angle| = {peak:.3g} rad > {max_angle_rad:g} rad "
            f"in [{t0:.6g}, {t1:.6g}] s (parameters unstable without saturation?)"
        )


def _check_params(params):
    bad = []
    for name in ("eta_alpha", "eta_beta", "ka_eff", "kb_eff"):
        v = getattr(params, name)
        if not (math.isfinite(v) and v > 0):
            bad.append(f"{name}={v!r} must be finite and > 0")
    for name in ("k_ab", "k1", "k2", "sigma", "alpha_star"):
        v = params.per_cell(name)
        if not np.all(np.isfinite(v)):
            bad.append(f"{name}={getattr(params, name)!r} must be finite")
    k1, k2, ast = params.per_cell("k1"), params.per_cell("k2"), params.per_cell("alpha_star")
    with np.errstate(divide="ignore", invalid="ignore"):
        if np.any((k1 != k2) & (k1 * ast / np.where(k1 != k2, k1 - k2, 1.0) < 0)):
            bad.append("psi' breakpoint k1*alpha_star/(k1-k2) is negative (need k1 > k2, alpha_star >= 0)")
    if bad:
        raise ValueError("invalid parameters for the continuum model: " + "; ".join(bad))


def simulate_continuum(
    params: Params,
    cells: int,
    t_end_s: float,
    perturbations: Sequence[dict] | None,
    *,
    dt_out_s: float = 0.01,
    points_per_cell: int = 4,
    rtol: float = 1e-6,
    atol: float = 1e-9,
    initial: Callable[..., tuple[np.ndarray, np.ndarray]] | None = None,
    max_angle_rad: float = 1e4,
    method: str = "auto",
    spread: tuple[np.ndarray, np.ndarray] | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Integrate the PDE from rest (or ``initial``) and return (t, alpha, beta) sampled at the cell centres.

    t: (T,) s from 0 to t_end_s every dt_out_s (t_end_s included); alpha, beta: (T, cells) rad.
    perturbations: dicts {cell (1-based), chain, torque_Nm, start_s, duration_s} (see module docstring).
    Per-cell reaction parameters (Params.per_cell) hold over each cell's interval [j-1, j] of x (piecewise constant).
    initial: optional callable x -> (alpha0, beta0) evaluated at the grid points x (cells, 0..cells),
        for linear-theory checks; default: rest. On a sheet it is called as initial(x, y) with the volume centres
        (each (rows M, cols M): x along a row, y down the rows, in cells; cell (r, c) covers [c-1, c] x [r-1, r]).
    spread: (band, eta) factors of plant.spreads (2, cells) each, the noise model's draws: bond b's stiffness
        factor holds on the grid's faces nearest to it (x in [b + 1/2, b + 3/2], the end faces take the end bonds),
        cell j's viscosity factor on its interval; None: none (the uniform equations above, as before).
    method: "auto" (a chain or ring: scipy "BDF"; a sheet: "etdrk4", continuum_sheet's exponential integrator),
        or a scipy method name ("BDF", "Radau", "LSODA"; any solve_ivp method on a chain).
    Raises ValueError for bad input, ContinuumError if the solver fails or |angle| exceeds max_angle_rad.
    """
    _check_params(params)
    if isinstance(cells, bool) or not isinstance(cells, (int, np.integer)) or cells < 1:
        raise ValueError(f"cells={cells!r} must be a positive integer")
    t_end_s, dt_out_s = float(t_end_s), float(dt_out_s)
    if not (math.isfinite(t_end_s) and t_end_s > 0):
        raise ValueError(f"t_end_s={t_end_s!r} must be finite and > 0")
    if not (math.isfinite(dt_out_s) and 0 < dt_out_s <= t_end_s):
        raise ValueError(f"dt_out_s={dt_out_s!r} must be in (0, t_end_s]")
    if isinstance(points_per_cell, bool) or not isinstance(points_per_cell, (int, np.integer)) or points_per_cell < 1:
        raise ValueError(f"points_per_cell={points_per_cell!r} must be a positive integer")
    pert = validate_perturbations(perturbations, cells)
    if params.cells != cells and params.per_cell_keys:
        raise ValueError(f"cells={cells} but the per-cell parameters give {params.cells} cells")

    topo = params.topology
    if topo.is_sheet:
        return _sheet(
            params, cells, t_end_s, dt_out_s, pert, points_per_cell, rtol, atol, initial, max_angle_rad, method, spread
        )
    if method == "auto":
        method = "BDF"
    if topo.periodic and spread is not None:
        raise ValueError("the noise model's band and viscosity spreads are not mapped onto a ring's continuum")

    m = int(points_per_cell)
    n = cells * m
    h = 1.0 / m
    x = (np.arange(n) + 0.5) * h
    lap = _laplacian(n, h) if not topo.periodic else _laplacian_ring(n, h)
    ea: float | np.ndarray = params.eta_alpha
    eb: float | np.ndarray = params.eta_beta
    if spread is None:
        da = (params.ka_eff / ea) * lap
        db = (params.kb_eff / eb) * lap
    else:
        band, eta = (np.asarray(v, dtype=float) for v in spread)
        ea = params.eta_alpha * np.repeat(eta[0, :cells], m)
        eb = params.eta_beta * np.repeat(eta[1, :cells], m)
        da = sp.diags(params.ka_eff / ea) @ _laplacian_weighted(n, h, _face_factors(band[0], cells, m))
        db = sp.diags(params.kb_eff / eb) @ _laplacian_weighted(n, h, _face_factors(band[1], cells, m))
    if params.per_cell_keys:
        # the law of grid point i is its cell's: per-point arrays, broadcast by physics.reaction
        law: object = SimpleNamespace(**{k: np.repeat(params.per_cell(k), m) for k in REACTION_KEYS})
    else:
        law = params

    y0 = np.zeros(2 * n)
    if initial is not None:
        a0, b0 = initial(x.copy())
        y0[:n] = np.broadcast_to(np.asarray(a0, dtype=float), (n,))
        y0[n:] = np.broadcast_to(np.asarray(b0, dtype=float), (n,))
        if not np.all(np.isfinite(y0)):
            raise ValueError("initial state is not finite")

    def forcing(t_mid):
        """Torque density per unit x on the grid, divided by eta, for the segment containing t_mid."""
        fa = np.zeros(n)
        fb = np.zeros(n)
        for p in pert:
            if p["start_s"] <= t_mid < p["start_s"] + p["duration_s"]:
                sl = slice((p["cell"] - 1) * m, p["cell"] * m)
                if p["chain"] == "alpha":
                    fa[sl] += p["torque_Nm"] / (ea[sl] if isinstance(ea, np.ndarray) else ea)
                else:
                    fb[sl] += p["torque_Nm"] / (eb[sl] if isinstance(eb, np.ndarray) else eb)
        return fa, fb

    make_rhs, jac = _rhs_and_jac(law, n, da, db, ea, eb)
    t_out, cuts = _output_times(t_end_s, dt_out_s, pert)

    ys = np.full((len(t_out), 2 * n), np.nan)
    ys[0] = y0
    y = y0
    for t0, t1 in zip(cuts[:-1], cuts[1:]):
        fa, fb = forcing(0.5 * (t0 + t1))
        sel, sol = _solve_cut(make_rhs(fa, fb), jac, y, t0, t1, t_out, method, rtol, atol)
        _check_state(sol.y, t0, t1, max_angle_rad)
        ys[sel] = sol.y[:, : sel.size].T
        y = sol.y[:, -1]

    if not np.all(np.isfinite(ys)):  # every output row must have been written
        raise ContinuumError("internal error: some output times were not reached by the integration")

    # linear interpolation of the grid to the cell centres x_c = j - 1/2
    xc = np.arange(cells) + 0.5
    samp = np.empty((cells, n))
    eye_n = np.eye(n)
    for j in range(n):
        samp[:, j] = np.interp(xc, x, eye_n[j])
    alpha = ys[:, :n] @ samp.T
    beta = ys[:, n:] @ samp.T
    return t_out, alpha, beta
