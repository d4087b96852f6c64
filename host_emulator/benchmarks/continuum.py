"""Continuum (continuum PDE, docs/physics.md#linear-stability) work-precision: our compiled lattice engine and scipy-BDF
path against py-pde, same grid.

The method-of-lines continuum with M points per cell (models/continuum.py) is, node by node,

    eta_a a_i' = k_a M^2 (a_{i-1} - 2 a_i + a_{i+1}) + R_a(a_i, b_i) + P_i,   zero-flux ends (ghost = edge value)
    eta_b b_i' = k_b M^2 (b_{i-1} - 2 b_i + b_{i+1}) + R_b(a_i, b_i)

which is exactly the overdamped lattice plant with linear bands of stiffness k M^2, N M cells, and the cell's
torque density T applied to each of its M nodes. So the compiled steppers (csrc/he_step.c) solve the PDE too;
`run_fast` does that. The reference is models/continuum.py's BDF at rtol 1e-10 on the same grid. py-pde's stepper
is compiled once per row and run once before its timing (each `PDE.solve` call compiles it anew: seconds of CPU
whatever the run's length), so its row times the stepping alone, as benchmarks/continuum2d.py does.
"""

from __future__ import annotations

import time
from collections.abc import Callable, Sequence
from functools import partial
from typing import TYPE_CHECKING, Any

import numpy as np

from ..models import make_model
from ..models.continuum import simulate_continuum
from ..models.options import ModelOptions, Perturbation
from ..physics import pypde_reaction
from ..scene import load_scene
from .common import WPPoint, best_time, max_err

if TYPE_CHECKING:
    from ..models.options import Perturbation
    from ..params import Params
    from ..scene import Scene

PDE_DT_GRID = (2e-5, 1e-5, 5e-6, 2.5e-6)


def centre_matrix(cells: int, m: int) -> np.ndarray:
    """(cells, cells*m) linear interpolation of the grid x_i = (i + 1/2)/m to the cell centres j - 1/2
    (the same sampling as models/continuum.py)."""
    n = cells * m
    x = (np.arange(n) + 0.5) / m
    xc = np.arange(cells) + 0.5
    eye = np.eye(n)
    return np.stack([np.interp(xc, x, eye[j]) for j in range(n)], axis=1)


def as_lattice(
    params: Params, cells: int, m: int, perturbations: Sequence[Perturbation]
) -> tuple[Params, list[Perturbation]]:
    """(params, perturbations) of the equivalent overdamped lattice with cells*m nodes."""
    p = params.with_overrides(cells=cells * m, k_a=params.k_a * m * m, k_b=params.k_b * m * m)
    perts = [
        Perturbation((q.cell - 1) * m + i + 1, q.chain, q.torque_Nm, q.start_s, q.duration_s)
        for q in perturbations
        for i in range(m)
    ]
    return p, perts


def run_fast(scene: Scene, stepper: str, dt: float, m: int) -> tuple[np.ndarray, float, float]:
    """The continuum on the compiled lattice engine; (T, 2*cells) at the cell centres."""
    p, perts = as_lattice(scene.params, scene.cells, m, scene.perturbations)
    model = make_model(
        "lattice",
        p,
        perts,
        ModelOptions(inertia=False, bands="linear", stepper=stepper, dt=dt, dt_out=scene.options.dt_out),
    )
    s = model.solver()
    n_out = int(round(scene.t_end_s / s.dt_out))
    nn = model.n
    out = np.empty((n_out + 1, 2 * nn))
    out[0] = s.x
    for k in range(n_out):
        s.advance()
        out[k + 1] = s.x
    S = centre_matrix(scene.cells, m)
    return np.concatenate([out[:, :nn] @ S.T, out[:, nn:] @ S.T], axis=1), s.h, s.limit


def run_bdf(scene: Scene, m: int, rtol: float, atol: float) -> np.ndarray:
    _, a, b = simulate_continuum(
        scene.params,
        scene.cells,
        scene.t_end_s,
        [q.as_dict() for q in scene.perturbations],
        dt_out_s=scene.options.dt_out,
        points_per_cell=m,
        rtol=rtol,
        atol=atol,
    )
    return np.concatenate([a, b], axis=1)


def pypde_problem(scene: Scene, m: int) -> tuple[Any, Any]:  # (pde.PDE, pde.FieldCollection)
    """py-pde formulation of the same PDE (expressions, numba-compiled by py-pde), zero-flux boundaries."""
    import pde

    p = scene.params
    ea, eb = p.eta_alpha, p.eta_beta
    ra, rb = pypde_reaction(p)  # the reaction law as py-pde expressions, built by physics.py
    fa: list[str] = []
    fb: list[str] = []
    for q in scene.perturbations:
        # torque density T over the cell [cell-1, cell], on for start <= t < end (sign(0) = 0: half at the edge)
        w = (
            f"((sign(t - {q.start_s!r}) - sign(t - {q.start_s + q.duration_s!r}))/2"
            f"*Heaviside(x - {q.cell - 1})*Heaviside({q.cell} - x))"
        )
        (fa if q.chain == "alpha" else fb).append(f" + {q.torque_Nm / (ea if q.chain == 'alpha' else eb)!r}*{w}")
    eqs = {
        "a": f"{p.ka_eff / ea!r}*laplace(a) + {ra}/{ea!r}" + "".join(fa),
        "b": f"{p.kb_eff / eb!r}*laplace(b) + {rb}/{eb!r}" + "".join(fb),
    }
    eq = pde.PDE(eqs, bc={"derivative": 0})
    grid = pde.CartesianGrid([(0.0, float(scene.cells))], [scene.cells * m])
    state = pde.FieldCollection([pde.ScalarField(grid, 0.0, label="a"), pde.ScalarField(grid, 0.0, label="b")])
    return eq, state


def pypde_stepper(scene: Scene, m: int, solver: str, **kw: Any) -> tuple[Any, Any]:
    """(stepper, initial state) of py-pde's solver, compiled and run once (0.1 ms) so that timing it measures the
    stepping alone: every `PDE.solve` call compiles its stepper anew (seconds of CPU, whatever the run's length),
    as benchmarks/continuum2d.py found."""
    import pde

    eq, state = pypde_problem(scene, m)
    kw = dict(kw)
    dt = kw.pop("dt")
    stepper = pde.solvers.base.SolverBase.from_name(solver, eq, backend="numba", **kw).make_stepper(state, dt=dt)
    stepper(state.copy(), 0.0, 1e-4)
    return stepper, state


def run_pypde(scene: Scene, m: int, stepper: Any, state: Any) -> np.ndarray:
    """The compiled stepper from t = 0 to t_end, stopping at every dt_out to record the state (what `PDE.solve`'s
    controller does with a storage tracker at that interval)."""
    s = state.copy()
    dt_out = scene.options.dt_out
    frames = [s.data.copy()]
    t = 0.0
    for k in range(1, int(round(scene.t_end_s / dt_out)) + 1):
        t = stepper(s, t, k * dt_out)
        frames.append(s.data.copy())
    data = np.array(frames)  # (T, 2, n)
    S = centre_matrix(scene.cells, m)
    return np.concatenate([data[:, 0] @ S.T, data[:, 1] @ S.T], axis=1)


def continuum_workprecision(
    t_end_s: float = 3.0, m: int = 4, quick: bool = False, log: Callable[..., None] = print
) -> tuple[Scene, list[WPPoint], bool]:
    scene = load_scene("continuum_single", [f"t_end_s={t_end_s}", f"model_options.points_per_cell={m}"])
    t0 = time.perf_counter()
    ref = run_bdf(scene, m, 1e-10, 1e-13)
    log(
        f"  reference: models/continuum.py BDF rtol 1e-10 atol 1e-13, {scene.cells} cells x {m} points "
        f"({time.perf_counter() - t0:.1f} s)"
    )
    points = []
    for st, grid in (
        ("imex_euler", (2e-4, 1e-4, 5e-5, 2.5e-5, 1.25e-5)),
        ("rk4", (3e-5, 1.5e-5, 7.5e-6)),
        ("noh_bathe", (2.5e-5, 1.25e-5, 6.25e-6)),
    ):
        for dt in grid[::2] if quick else grid:
            try:
                (x, h, lim), w = best_time(partial(run_fast, scene, st, dt, m), repeat=3)
            except ValueError as e:
                log(f"  continuum {st} dt {dt:g}: {e}")
                continue
            points.append(WPPoint(f"lattice-engine {st}", f"dt={h:.3g}", w, max_err(x, ref)))
    for rtol in (1e-4, 1e-6, 1e-8) if not quick else (1e-4, 1e-7):
        x, w = best_time(partial(run_bdf, scene, m, rtol, rtol * 1e-3), repeat=2, budget_s=3.0)
        points.append(WPPoint("continuum.py BDF", f"rtol={rtol:g}", w, max_err(x, ref)))
    try:
        import pde  # noqa: F401
    except ImportError:
        log("  py-pde not installed: its rows are skipped (install with: .venv/bin/pip install -e '.[bench]')")
        return scene, points, False
    runs = [("euler", dict(dt=dt)) for dt in ((2e-5, 5e-6) if not quick else (2e-5,))]
    runs += [
        ("runge-kutta", dict(dt=1e-5, adaptive=True, tolerance=tol)) for tol in ((1e-4, 1e-6) if not quick else (1e-5,))
    ]
    for solver, kw in runs:
        (stepper, state), w = best_time(partial(pypde_stepper, scene, m, solver, **kw), repeat=1)
        log(f"  py-pde {solver}: compilation of the stepper and a 0.1 ms run {w:.1f} s cpu (not in its row)")
        x, w = best_time(partial(run_pypde, scene, m, stepper, state), repeat=1)
        setting = ", ".join(f"{k}={v:g}" if isinstance(v, float) else f"{k}={v}" for k, v in kw.items())
        points.append(WPPoint(f"py-pde {solver}", setting, w, max_err(x, ref)))
    return scene, points, True
