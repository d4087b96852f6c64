"""Work-precision of the emulator's steppers against scipy solve_ivp, diffrax and CVODE (lattice), a fine-step hil
run (hil) and py-pde (continuum).

Every method is run at several step sizes / tolerances; its error is the max |angle - reference| over all
output samples (every 10 ms), cells and both chains, its cost the CPU time of a run on one pinned core (ours and
the compiled peers: the median of several runs; scipy: the best of a few). The lattice reference is scipy's
DOP853 at rtol 1e-12 on the same right-hand side, restarted at every perturbation edge: independent of our C
integrators. Wall time at a target error is interpolated on each method's Pareto front (common.wall_at); the
lattice front (front_ratios) compares the best of ours with the best peer at every error from 1e-3 to 1e-8 rad.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import replace
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from ..controller import build_solver
from ..models.hil import HilSolver
from ..models.lattice import LatticeModel, LatticeSolver
from ..models.reference import ReferencePlant
from ..scene import load_scene
from .common import WPPoint, best_time, fmt, max_err, median_time, table, wall_at

if TYPE_CHECKING:
    from ..models.hil import HilSolver
    from ..models.lattice import LatticeSolver
    from ..scene import Scene

LATTICE_STEPPERS = ("euler", "symplectic_euler", "imex_euler", "noh_bathe", "rk4")
DT_GRID = (2e-3, 1e-3, 5e-4, 2.5e-4, 1.25e-4, 6.25e-5, 3.125e-5)
ADAPTIVE_STEPPERS = ("dop853",)
TOL_GRID = tuple(10.0 ** (-k / 2) for k in range(4, 23))  # 1e-2 .. 1e-11, half decades
SCIPY_METHODS = ("RK45", "DOP853", "LSODA")
TARGET = 1e-4
PEERS = ("scipy", "py-pde", "diffrax", "CVODE")  # method-name prefixes that are not ours
REF_RTOL, REF_ATOL = 1e-12, 1e-14  # the lattice reference (tighter fails: the step underflows at the kinks)
FRONT_TOLS = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8)  # max angle errors of the lattice front (rad)
FRONT_PEERS = ("diffrax", "CVODE", "scipy")  # families, each represented by its best method at each error
FRONT_TARGET = 2.0  # best peer / best ours at every error of the front


# ---------------------------------------------------------------- lattice
def lattice_scene(t_end_s: float = 3.0, cells: int = 16) -> Scene:
    """experiment 3 (docs/physics.md#experiments) as a lattice scene: 16 cells, sigma 9/125, a 20 mN*m push on alpha_8
    at 0.1-0.2 s."""
    return load_scene("exp3_single_sigma9", [f"t_end_s={t_end_s}", f"cells={cells}"])


def output_times(t_end_s: float, dt_out: float) -> np.ndarray:
    n = int(round(t_end_s / dt_out))
    return np.arange(n + 1) * dt_out


def _sampled_states(solver: LatticeSolver | HilSolver, t_end_s: float, n: int) -> np.ndarray:
    """States (T, 2n) of a compiled solver at t = 0, dt_out, ..., t_end: one advance_many call (the compiled
    sampled loop a run uses), so the time is the integrator's, not Python's per sample."""
    n_out = int(round(t_end_s / solver.dt_out))
    out = np.empty((n_out + 1, 2 * n))
    out[0] = solver.x
    _, a, b = solver.advance_many(n_out)
    out[1:, :n] = a
    out[1:, n:] = b
    return out


def run_ours(scene: Scene, stepper: str, dt: float | None = None, tol: float | None = None) -> tuple[np.ndarray, dict]:
    """Trajectory (T, 2n) of the compiled lattice at the output times with a stepper and its largest step dt (an
    adaptive one: its tolerance tol), and the solver's info (steps, evaluations)."""
    s = build_solver(scene, resolve=False, options=replace(scene.options, stepper=stepper, dt=dt, tol=tol))
    if not isinstance(s, LatticeSolver):
        raise TypeError(f"scene {scene.name!r} (model {scene.model!r}) is not a lattice scene")
    x = _sampled_states(s, scene.t_end_s, s.model.n)
    return x, s.info()


def _cuts(scene):
    cuts = {0.0, scene.t_end_s}
    for q in scene.perturbations:
        for tb in (q.start_s, q.start_s + q.duration_s):
            if 0 < tb < scene.t_end_s:
                cuts.add(tb)
    return sorted(cuts)


def solve_segments(
    rhs: Callable[[float, np.ndarray], np.ndarray],
    y0: np.ndarray,
    scene: Scene,
    t_eval: np.ndarray,
    method: str,
    rtol: float,
    atol: float,
) -> tuple[np.ndarray, int]:
    """solve_ivp restarted at every perturbation edge (what a careful researcher does: no step across a jump)."""
    from scipy.integrate import solve_ivp

    cuts = _cuts(scene)
    ys = [np.asarray(y0, float)]
    y = ys[0]
    nfev = 0
    for a, b in zip(cuts[:-1], cuts[1:]):
        te = t_eval[(t_eval > a + 1e-12) & (t_eval <= b + 1e-12)]
        sol = solve_ivp(rhs, (a, b), y, method=method, rtol=rtol, atol=atol, t_eval=te)
        if not sol.success:
            raise RuntimeError(f"{method}: {sol.message}")
        ys.extend(sol.y.T)
        y = sol.y[:, -1]
        nfev += sol.nfev
    return np.array(ys), nfev


def numpy_rhs(scene: Scene) -> Callable[[float, np.ndarray], np.ndarray]:
    """First-order rhs y = [x, v] of the numpy reference plant (models/reference.py): what a researcher writes."""
    ref = ReferencePlant(scene.params, scene.options, scene.perturbations)
    n2 = 2 * ref.n
    inv_i = 1.0 / ref.I

    def rhs(t, y):
        F, C = ref.forces(t, y[:n2])
        v = y[n2:]
        return np.concatenate([v, (F - C * v) * inv_i])

    return rhs


def compiled_rhs(scene: Scene) -> Callable[[float, np.ndarray], np.ndarray]:
    """The same rhs on the compiled plant (he_plant_forces): the reference is solved on exactly our physics."""
    m = LatticeModel(scene.params, scene.perturbations, scene.options)
    n2 = 2 * m.n
    inv_i = 1.0 / np.r_[np.full(m.n, scene.params.I_a), np.full(m.n, scene.params.I_b)]

    def rhs(t, y):
        F, C = m.forces(t, y[:n2])
        v = y[n2:]
        return np.concatenate([v, (F - C * v) * inv_i])

    return rhs


def lattice_workprecision(
    t_end_s: float = 3.0, quick: bool = False, log: Callable[..., None] = print, peers: bool = True
) -> tuple[Scene, list[WPPoint], float]:
    scene = lattice_scene(t_end_s)
    n2 = 2 * scene.cells
    t_eval = output_times(scene.t_end_s, scene.options.dt_out)
    y0 = np.zeros(2 * n2)
    t0 = time.perf_counter()
    ref, nfev = solve_segments(compiled_rhs(scene), y0, scene, t_eval, "DOP853", REF_RTOL, REF_ATOL)
    ref_x = ref[:, :n2]
    log(
        f"  reference: scipy DOP853 rtol {REF_RTOL:g} atol {REF_ATOL:g} on the compiled rhs, {nfev} rhs calls, "
        f"{time.perf_counter() - t0:.2f} s"
    )
    points: list[WPPoint] = []
    for st in LATTICE_STEPPERS:
        lim, chain = LatticeModel(scene.params, scene.perturbations, replace(scene.options, stepper=st)).step_limit()
        grid = [dt for dt in DT_GRID if dt <= lim]
        if st == "euler":
            grid = [dt for dt in (lim / 2, lim / 4, lim / 8) if dt > 0]
        if quick:
            grid = grid[::2]
        for dt in grid:
            (x, info), w = median_time(partial(run_ours, scene, st, dt), repeat=5, budget_s=1.0)
            points.append(WPPoint(st, f"dt={info['dt_s']:.3g}", w, max_err(x, ref_x), extra={"limit_s": lim}))
    for st in ADAPTIVE_STEPPERS:
        for tol in TOL_GRID[::3] if quick else TOL_GRID:
            (x, info), w = median_time(partial(run_ours, scene, st, None, tol), repeat=5, budget_s=1.0)
            extra = {k: info[k] for k in ("steps", "rejected_steps", "switch_landings", "force_evaluations")}
            points.append(WPPoint(st, f"tol={tol:.2g}", w, max_err(x, ref_x), extra=extra))
    rhs = numpy_rhs(scene)
    rtols = (1e-3, 1e-4, 1e-5, 1e-6, 1e-7, 1e-8) if not quick else (1e-3, 1e-5, 1e-7)
    for meth in SCIPY_METHODS:
        for rtol in rtols:
            try:
                (y, nf), w = best_time(
                    partial(solve_segments, rhs, y0, scene, t_eval, meth, rtol, rtol * 1e-2), repeat=2, budget_s=1.0
                )
                err = max_err(y[:, :n2], ref_x)
            except RuntimeError as e:
                w, err, nf = math.nan, math.inf, 0
                log(f"  scipy {meth} rtol {rtol:g}: {e}")
            points.append(WPPoint(f"scipy {meth}", f"rtol={rtol:g}", w, err, extra={"nfev": nf}))
    if peers:
        from .peers import peer_points

        points += peer_points(scene, t_eval, y0, ref_x, quick=quick, log=log)
    # cross-check of the reference: the numpy rhs solved as tightly
    (y, _), w = best_time(lambda: solve_segments(rhs, y0, scene, t_eval, "DOP853", REF_RTOL, REF_ATOL), repeat=1)
    ref_check = max_err(y[:, :n2], ref_x)
    log(f"  reference check: numpy rhs, DOP853 rtol {REF_RTOL:g} differs from the reference by {ref_check:.2g} rad")
    return scene, points, ref_check


def is_ours(method: str) -> bool:
    return not method.startswith(PEERS)


def front_ratios(points: list[WPPoint], tols: tuple[float, ...] = FRONT_TOLS) -> list[dict]:
    """For each max angle error in `tols`: the cheapest of ours and of each peer family there (wall_at on each
    method's Pareto front), and best peer / best ours. Keys: tol_rad, ours_ms, ours_method, best_peer, peer_ms,
    ratio (None where nobody of a side reaches the error), and peers: {family: {method, ms, ratio}}."""
    methods = sorted({p.method for p in points})
    rows = []
    for tol in tols:
        at = {m: wall_at([p for p in points if p.method == m], tol) for m in methods}
        reach = {m: w for m, w in at.items() if w is not None}
        ours = {m: w for m, w in reach.items() if is_ours(m)}
        best_ours = min(ours.items(), key=lambda kv: kv[1]) if ours else None
        fams: dict[str, dict] = {}
        for fam in FRONT_PEERS:
            cand = {m: w for m, w in reach.items() if m.startswith(fam)}
            if cand:
                m, w = min(cand.items(), key=lambda kv: kv[1])
                fams[fam] = {"method": m, "ms": w * 1e3, "ratio": w / best_ours[1] if best_ours else None}
        best_peer = min(fams.values(), key=lambda d: d["ms"]) if fams else None
        rows.append(
            {
                "tol_rad": tol,
                "ours_ms": best_ours[1] * 1e3 if best_ours else None,
                "ours_method": best_ours[0] if best_ours else None,
                "best_peer": best_peer["method"] if best_peer else None,
                "peer_ms": best_peer["ms"] if best_peer else None,
                "ratio": best_peer["ratio"] if best_peer else None,
                "peers": fams,
            }
        )
    return rows


def _ratio(r: float | None) -> str:
    return "-" if r is None else f"{r:.1f}x" if r < 100 else f"{r:.0f}x"


def front_table(rows: list[dict]) -> str:
    """The lattice front as printed: per error, ours and each peer family with its ratio to ours."""
    out = []
    for r in rows:
        cells = [f"{r['tol_rad']:g}", f"{fmt(r['ours_ms'])} ({r['ours_method'] or 'none'})"]
        for fam in FRONT_PEERS:
            d = r["peers"].get(fam)
            cells.append(
                f"{fmt(d['ms'])} ({d['method'].split(' ', 1)[1]}) {_ratio(d['ratio'])}" if d else "not reached"
            )
        cells.append(_ratio(r["ratio"]))
        out.append(cells)
    return table(
        out, ["max error rad", "ours ms (method)", *(f"{f} ms, ratio" for f in FRONT_PEERS), "best peer / ours"]
    )


def summarize(
    points: list[WPPoint], target: float = TARGET, ours_prefix: tuple[str, ...] = ("scipy", "py-pde")
) -> tuple[dict[str, float | None], tuple[str, float] | None, tuple[str, float] | None]:
    """{method: wall at target} and the best of ours / of the peers."""
    methods = sorted({p.method for p in points})
    at = {m: wall_at([p for p in points if p.method == m], target) for m in methods}
    ours = {m: w for m, w in at.items() if not m.startswith(ours_prefix + PEERS) and w is not None}
    peers = {m: w for m, w in at.items() if m.startswith(ours_prefix) and w is not None}
    best_ours = min(ours.items(), key=lambda kv: kv[1]) if ours else None
    best_peer = min(peers.items(), key=lambda kv: kv[1]) if peers else None
    return at, best_ours, best_peer


def points_table(points: list[WPPoint]) -> str:
    rows = [[p.method, p.setting, fmt(p.wall_s * 1e3), fmt(p.error, 2)] for p in points]
    return table(rows, ["method", "setting", "cpu ms", "max error rad"])


# ---------------------------------------------------------------- hil
HIL_STEPPERS = ("symplectic_euler", "imex_euler", "noh_bathe", "rk4")


def run_hil(scene: Scene, stepper: str, substeps: int) -> np.ndarray:
    opts = replace(scene.options, stepper=stepper, substeps=substeps, dt=None)
    s = build_solver(scene, resolve=False, options=opts)
    if not isinstance(s, HilSolver):
        raise TypeError(f"scene {scene.name!r} (model {scene.model!r}) is not a hil scene")
    return _sampled_states(s, scene.t_end_s, s.model.n)


def hil_workprecision(
    t_end_s: float = 3.0, quick: bool = False, log: Callable[..., None] = print
) -> tuple[Scene, list[WPPoint]]:
    """The default hil scene (16 cells, 2 kHz firmware) with 1..8 plant steps per control tick, against the
    same loop at 64 RK4 plant steps per tick (the firmware is discrete: the control rate stays)."""
    scene = load_scene("default", [f"t_end_s={t_end_s}"])
    ref = run_hil(scene, "rk4", 64)
    h_ref = 1 / scene.params.control_rate_hz / 64
    log(f"  reference: the same hil loop, rk4, 64 plant steps per control tick ({h_ref:.3g} s)")
    points = []
    subs = (1, 2, 4, 8) if not quick else (1, 4)
    for st in HIL_STEPPERS:
        for m in subs:
            try:
                x, w = best_time(partial(run_hil, scene, st, m), repeat=3)
                err = max_err(x, ref)
            except ValueError as e:  # sub-step above the stable limit
                log(f"  hil {st} x{m}: {e}")
                continue
            points.append(WPPoint(st, f"substeps={m}", w, err))
    return scene, points
