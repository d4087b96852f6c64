"""The continuum PDE on a square sheet: models/continuum.py (ETDRK4 on the grid's FFT) against py-pde, same grid, same
initial state, same run; CPU time and error against a fine-tolerance reference.

    python -m host_emulator.benchmarks.continuum2d                  # 64 x 64 and 128 x 128 cells, M = 1 and 2
    python -m host_emulator.benchmarks.continuum2d --sizes 32 --ppc 1 --quick

The case: sigma = 9/125 (stationary pattern, fastest wavelength 10 cells, growth 24.5/s), a periodic sheet of
n x n cells with M x M volumes per cell, from alpha = uniform noise in [-0.05, 0.05] rad per cell (seeded, each
cell's value on its M x M volumes), beta = 0, for t_end = 0.5 s: the pattern grows out of the noise and
saturates on psi's outer branches (|alpha| ~ 0.7 rad > the breakpoint 0.59 rad). py-pde gets the same PDE as
expressions (physics.pypde_reaction), numba-compiled, on CartesianGrid([(0, n), (0, n)], [n M, n M],
periodic): the same 5-point Laplacian on the same cell-centred grid, so both solve the same ODE system and only
the time integration differs. py-pde's solvers: explicit Euler (fixed dt, near its stability limit) and its
adaptive Runge-Kutta-Fehlberg 4(5) (max-norm absolute tolerance). The error is max |x - x_ref| over the final
alpha and beta at the cell centres; the reference is models/continuum.py's ETDRK4 at rtol 1e-8 (its agreement
with py-pde's tightest run is printed: the two references differ by less than either's error).
CPU time: process time of one run; py-pde's stepper is compiled and called once before (each `PDE.solve` call
compiles its stepper anew: seconds whatever the run's length, so its own time is printed apart), both
single-threaded (py-pde's numba multithreading, on by default from 256^2 grid points, is turned off).
"""

from __future__ import annotations

import argparse
import os
import platform
import time
from typing import Any

import numpy as np

from ..models.continuum import simulate_continuum
from ..params import Params
from ..physics import pypde_reaction

T_END = 0.5
REF_RTOL = 1e-8
SIGMA = 9 / 125


def case(n: int, m: int, seed: int = 1) -> tuple[Params, np.ndarray]:
    """(params, alpha0 per volume (n M, n M)) of the benchmark's sheet."""
    p = Params(sigma=SIGMA, cells=n * n, shape=(n, n), lattice="square", boundary="periodic")
    a0 = np.random.default_rng(seed).uniform(-0.05, 0.05, (n, n))
    return p, np.repeat(np.repeat(a0, m, axis=0), m, axis=1)


def cells_of(u: np.ndarray, m: int) -> np.ndarray:
    """(R, C) volumes -> (n*n,) cell centres (models/continuum_sheet.SheetGrid.sampler's rule)."""
    from ..models.continuum_sheet import SheetGrid
    from ..topology import Topology

    n = u.shape[0] // m
    return SheetGrid(Topology((n, n), "square", True), m).sampler()(u)


def run_ours(n: int, m: int, rtol: float, method: str = "etdrk4") -> np.ndarray:
    """Final (alpha, beta) at the cell centres, (2, n*n)."""
    p, a0 = case(n, m)

    def initial(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return a0, np.zeros_like(a0)

    _, a, b = simulate_continuum(
        p,
        p.cells,
        T_END,
        [],
        dt_out_s=T_END,
        points_per_cell=m,
        rtol=rtol,
        atol=rtol * 1e-3,
        initial=initial,
        method=method,
    )
    return np.stack([a[-1], b[-1]])


def pypde_problem(n: int, m: int) -> tuple[Any, Any]:
    import pde

    pde.config["backend.numba.multithreading"] = "never"  # one core each (ours: scipy.fft with one worker)
    p, a0 = case(n, m)
    ea, eb = p.eta_alpha, p.eta_beta
    ra, rb = pypde_reaction(p)
    eq = pde.PDE(
        {"a": f"{p.ka_eff / ea!r}*laplace(a) + {ra}/{ea!r}", "b": f"{p.kb_eff / eb!r}*laplace(b) + {rb}/{eb!r}"},
        bc="periodic",
    )
    grid = pde.CartesianGrid([(0.0, float(n)), (0.0, float(n))], [n * m, n * m], periodic=True)
    state = pde.FieldCollection([pde.ScalarField(grid, a0, label="a"), pde.ScalarField(grid, 0.0, label="b")])
    return eq, state


def pypde_stepper(n: int, m: int, solver: str, **kw: Any) -> tuple[Any, Any]:
    """(stepper, initial state) of py-pde's solver, compiled and run once (0.1 ms) so that timing it measures the
    stepping alone: every `PDE.solve` call compiles its stepper anew (seconds, whatever the run's length)."""
    import pde

    eq, state = pypde_problem(n, m)
    dt = kw.pop("dt")
    stepper = pde.solvers.base.SolverBase.from_name(solver, eq, backend="numba", **kw).make_stepper(state, dt=dt)
    stepper(state.copy(), 0.0, 1e-4)
    return stepper, state


def run_pypde(stepper: Any, state: Any, m: int) -> np.ndarray:
    s = state.copy()
    stepper(s, 0.0, T_END)
    return np.stack([cells_of(s[0].data, m), cells_of(s[1].data, m)])


def timed(f, *a, **kw) -> tuple[Any, float]:
    t0 = time.process_time()
    r = f(*a, **kw)
    return r, time.process_time() - t0


def err(x: np.ndarray, ref: np.ndarray) -> float:
    return float(np.max(np.abs(x - ref)))


def bench(n: int, m: int, quick: bool, log=print) -> list[tuple[str, str, float, float]]:
    from ..models.continuum_sheet import SheetGrid  # noqa: F401  (import time outside the timings)

    log(f"\n== {n} x {n} cells x {m}x{m} volumes (periodic), {2 * (n * m) ** 2} unknowns, t_end {T_END} s ==")
    ref, w = timed(run_ours, n, m, REF_RTOL)
    log(f"  reference: ours ETDRK4 rtol {REF_RTOL:g} ({w:.1f} s cpu)", flush=True)
    rows = []
    for rtol in (1e-3, 1e-5) if quick else (1e-3, 1e-4, 1e-5, 1e-6):
        x, w = timed(run_ours, n, m, rtol)
        rows.append(("ours ETDRK4", f"rtol={rtol:g}", w, err(x, ref)))
        log(f"  ... {rows[-1][0]} {rows[-1][1]}: {w:.2f} s cpu, max error {rows[-1][3]:.2g} rad", flush=True)
    try:
        import pde  # noqa: F401
    except ImportError:
        log("  py-pde not installed: its rows are skipped (.venv/bin/pip install -e '.[bench]')")
        return rows
    p, _ = case(n, m)
    stiff = 8.0 * m * m * p.kb_eff / p.eta_beta  # largest |eigenvalue| of the beta diffusion
    euler_dts = [1.8 / stiff, 1.0 / stiff] if not quick else [1.8 / stiff]
    runs: list[tuple[str, dict]] = [("euler", dict(dt=dt)) for dt in euler_dts]
    runs += [
        ("runge-kutta", dict(dt=1e-5, adaptive=True, tolerance=tol)) for tol in ((1e-4, 1e-6) if not quick else (1e-5,))
    ]
    tight = None
    for solver, kw in runs:
        (stepper, state), w = timed(pypde_stepper, n, m, solver, **kw)
        log(f"  py-pde {solver}: compilation and a 0.1 ms run {w:.1f} s cpu (not in its row)", flush=True)
        x, w = timed(run_pypde, stepper, state, m)
        setting = ", ".join(f"{k}={v:.3g}" if isinstance(v, float) else f"{k}={v}" for k, v in kw.items())
        rows.append((f"py-pde {solver}", setting, w, err(x, ref)))
        log(f"  ... {rows[-1][0]} {rows[-1][1]}: {w:.2f} s cpu, max error {rows[-1][3]:.2g} rad", flush=True)
        if solver == "runge-kutta":
            tight = x
    if tight is not None:
        log(f"  references: max |ours rtol {REF_RTOL:g} - py-pde's tightest RK| = {err(tight, ref):.2g} rad")
    return rows


def ratio_line(rows, target: float) -> str:
    ours = [r for r in rows if r[0].startswith("ours") and r[3] <= target]
    peer = [r for r in rows if r[0].startswith("py-pde") and r[3] <= target]
    if not ours or not peer:
        return f"  RATIO at max error {target:g} rad: not reached by both"
    o = min(ours, key=lambda r: r[2])
    q = min(peer, key=lambda r: r[2])
    return (
        f"  RATIO at max error {target:g} rad: best py-pde ({q[0]} {q[1]}, {q[2]:.2f} s) / best ours "
        f"({o[0]} {o[1]}, {o[2]:.2f} s) = {q[2] / o[2]:.1f}x (target >= 5x)"
    )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(
        prog="python -m host_emulator.benchmarks.continuum2d", description=__doc__.splitlines()[0]
    )
    ap.add_argument("--sizes", type=int, nargs="+", default=[64, 128], help="sheet sizes n (n x n cells)")
    ap.add_argument("--ppc", type=int, nargs="+", default=[1, 2], help="points (volumes) per cell side M")
    ap.add_argument("--quick", action="store_true", help="fewer tolerances")
    args = ap.parse_args(argv)
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    print(
        f"# continuum2d on {platform.machine()} {platform.processor() or ''} ({os.cpu_count()} cpus), "
        f"python {platform.python_version()}, load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}"
    )
    for n in args.sizes:
        for m in args.ppc:
            rows = bench(n, m, args.quick)
            print(f"  {'method':<20} {'setting':<42} {'cpu s':>8} {'max error rad':>14}")
            for r in rows:
                print(f"  {r[0]:<20} {r[1]:<42} {r[2]:>8.2f} {r[3]:>14.2g}")
            for target in (1e-3, 1e-4):
                print(ratio_line(rows, target))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
