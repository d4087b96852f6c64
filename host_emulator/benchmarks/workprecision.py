"""Work-precision of the emulator's steppers against scipy solve_ivp (lattice), a fine-step hil run (hil) and py-pde
(continuum).

Every method is run at several step sizes / tolerances; its error is the max |angle - reference| over all
output samples (every 10 ms), cells and both chains, its cost the best wall time of a few runs on one
core. The reference is solved tightly on the same right-hand side (DOP853, rtol 1e-10, restarted at every
perturbation edge). Wall time at a target error is interpolated on each method's Pareto front
(common.wall_at); the ratio best-scipy / best-ours is the headline figure.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import replace
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from .common import WPPoint, best_time, fmt, max_err, table, wall_at

if TYPE_CHECKING:
    from ..models.hil import HilSolver
    from ..models.lattice import LatticeSolver
    from ..scene import Scene

LATTICE_STEPPERS = ("euler", "symplectic_euler", "imex_euler", "noh_bathe", "rk4")
DT_GRID = (2e-3, 1e-3, 5e-4, 2.5e-4, 1.25e-4, 6.25e-5, 3.125e-5)
SCIPY_METHODS = ("RK45", "DOP853", "LSODA")
TARGET = 1e-4
PEERS = ("scipy", "py-pde", "diffrax", "CVODE")  # method-name prefixes that are not ours


# ---------------------------------------------------------------- lattice
def lattice_scene(t_end_s: float = 3.0, cells: int = 16) -> Scene:
    """experiment 3 (docs/physics.md#experiments) as a lattice scene: 16 cells, sigma 9/125, a 20 mN*m push on alpha_8
    at 0.1-0.2 s."""
    from ..scene import load_scene

    return load_scene("exp3_single_sigma9", [f"t_end_s={t_end_s}", f"cells={cells}"])


def output_times(t_end_s: float, dt_out: float) -> np.ndarray:
    n = int(round(t_end_s / dt_out))
    return np.arange(n + 1) * dt_out


def _sampled_states(solver: LatticeSolver | HilSolver, t_end_s: float, n: int) -> np.ndarray:
    """States (T, 2n) of a compiled solver at t = 0, dt_out, ..., t_end."""
    n_out = int(round(t_end_s / solver.dt_out))
    out = np.empty((n_out + 1, 2 * n))
    out[0] = solver.x
    for k in range(n_out):
        solver.advance()
        out[k + 1] = solver.x
    return out


def run_ours(scene: Scene, stepper: str, dt: float) -> tuple[np.ndarray, float]:
    """Trajectory (T, 2n) of the compiled lattice at the output times, stepper and largest step dt."""
    from ..controller import build_solver
    from ..models.lattice import LatticeSolver

    s = build_solver(scene, resolve=False, options=replace(scene.options, stepper=stepper, dt=dt))
    if not isinstance(s, LatticeSolver):
        raise TypeError(f"scene {scene.name!r} (model {scene.model!r}) is not a lattice scene")
    return _sampled_states(s, scene.t_end_s, s.model.n), s.h


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
    from ..models.reference import ReferencePlant

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
    from ..models.lattice import LatticeModel

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
    ref, nfev = solve_segments(compiled_rhs(scene), y0, scene, t_eval, "DOP853", 1e-10, 1e-12)
    ref_x = ref[:, :n2]
    log(
        f"  reference: DOP853 rtol 1e-10 atol 1e-12 on the compiled rhs, {nfev} rhs calls, "
        f"{time.perf_counter() - t0:.2f} s"
    )
    points: list[WPPoint] = []
    from ..models.lattice import LatticeModel

    for st in LATTICE_STEPPERS:
        lim, chain = LatticeModel(scene.params, scene.perturbations, replace(scene.options, stepper=st)).step_limit()
        grid = [dt for dt in DT_GRID if dt <= lim]
        if st == "euler":
            grid = [dt for dt in (lim / 2, lim / 4, lim / 8) if dt > 0]
        if quick:
            grid = grid[::2]
        for dt in grid:
            (x, h), w = best_time(partial(run_ours, scene, st, dt), repeat=3)
            points.append(WPPoint(st, f"dt={h:.3g}", w, max_err(x, ref_x), extra={"limit_s": lim}))
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
    (y, _), w = best_time(lambda: solve_segments(rhs, y0, scene, t_eval, "DOP853", 1e-10, 1e-12), repeat=1)
    ref_check = max_err(y[:, :n2], ref_x)
    log(f"  reference check: numpy rhs, DOP853 rtol 1e-10 differs from the reference by {ref_check:.2g} rad")
    return scene, points, ref_check


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
    from ..controller import build_solver
    from ..models.hil import HilSolver

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
    from ..scene import load_scene

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
