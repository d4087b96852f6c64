"""Compiled peers in the lattice work-precision table: diffrax (JAX, jit-compiled, warm) and SUNDIALS CVODE.

Both solve the same lattice scene as scipy and our steppers, restarted at every perturbation edge (no step
across a jump of the forcing), and are compared on the same reference and output samples, at tolerances from
1e-3 to 1e-11 (half decades, atol = rtol / 100) so that each reaches the tightest error of the front.

* diffrax (Tsit5, Dopri5, Dopri8 and the implicit Kvaerno5, each with its PID step controller): the
  right-hand side is the reference plant's equations written in jax.numpy, float64, one jit-compiled solve per
  segment with the tolerances as traced arguments (compiled once per solver). The time is the median of warm
  calls; the compile time (first call minus a warm one) is reported separately in the log.
* CVODE (scikit-sundae; Adams for this non-stiff problem, BDF beside it): its only right-hand side is a Python
  callable, so it gets the fastest one here: the compiled plant's forces (he_plant_forces through cffi), with
  the derivative written in place.

A peer whose package is missing is skipped with one line (they live in the `bench` extra only).
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from functools import partial
from typing import TYPE_CHECKING

import numpy as np

from .. import params as P
from ..models.reference import ReferencePlant
from .common import WPPoint, clock, max_err, median_time
from .workprecision import _cuts, compiled_rhs

if TYPE_CHECKING:
    from ..scene import Scene

# tolerances down to where every peer's error is below the tightest target of the front (1e-8 rad)
RTOLS = tuple(10.0 ** (-k / 2) for k in range(6, 23))  # 1e-3 .. 1e-11, half decades
RTOLS_QUICK = (1e-3, 1e-5, 1e-7, 1e-9, 1e-11)
ATOL_FACTOR = 1e-2  # atol = rtol / 100 (angles and speeds both)
REPEAT = 5  # timed runs per point; the median is kept
PEER_PREFIXES = ("diffrax", "CVODE")
# diffrax's explicit pairs (5th order: Tsit5, Dopri5; 8th: Dopri8) and one L-stable ESDIRK (Kvaerno5), each at
# every tolerance: the front takes the best per accuracy
DIFFRAX_SOLVERS = ("Tsit5", "Dopri5", "Dopri8", "Kvaerno5")
# Kvaerno5 (implicit: a Newton solve per stage) took 52 ms at rtol 1e-3 and 0.36 s at 1e-6 here (2.3e-5 rad; Dopri8
# needs 13 ms for 3e-6 rad): its tighter runs would take minutes each and never lead, so they are not run
DIFFRAX_TIGHTEST = {"Kvaerno5": 1e-6}


def rtols(quick: bool) -> tuple[float, ...]:
    return RTOLS_QUICK if quick else RTOLS


def _segments(scene, t_eval):
    cuts = _cuts(scene)
    segs = []
    for a, b in zip(cuts[:-1], cuts[1:]):
        te = t_eval[(t_eval > a + 1e-12) & (t_eval <= b + 1e-12)]
        segs.append((a, b, te))
    return segs


def _pert_vector(scene, n, t):
    P = np.zeros(2 * n)  # external torque on each cylinder over the segment starting at t
    for q in scene.perturbations:
        if q.start_s <= t < q.start_s + q.duration_s:
            P[(0 if q.chain == "alpha" else n) + q.cell - 1] += q.torque_Nm
    return P


# ---------------------------------------------------------------- diffrax
def diffrax_points(
    scene: Scene,
    t_eval: np.ndarray,
    y0: np.ndarray,
    ref_x: np.ndarray,
    quick: bool = False,
    log: Callable[..., None] = print,
) -> list[WPPoint]:
    try:
        import jax

        jax.config.update("jax_enable_x64", True)
        import diffrax
        import jax.numpy as jnp
    except ImportError as e:
        log(f"  diffrax: skipped ({e.name or e} not installed; pip install -e '.[bench]')")
        return []
    if scene.options.bands != "cubic" or scene.options.beta_geometry != "small":
        log("  diffrax: skipped (the jax right-hand side covers cubic bands with small-angle beta only)")
        return []
    ref = ReferencePlant(scene.params, scene.options, scene.perturbations)
    p, n = scene.params.uniform(), ref.n
    band = jnp.asarray(ref.band)
    eta, inv_i = jnp.asarray(ref.eta), jnp.asarray(1.0 / ref.I)
    f0 = (P.BAND_A_COEF[0] if p.slack_f0 else 0.0, P.BAND_B_COEF[0] if p.slack_f0 else 0.0)
    coefs = (P.BAND_A_COEF, P.BAND_B_COEF)
    d0s = (P.DELTA_A0_M, P.DELTA_B0_M)
    levers = (P.R_ALPHA_M, P.R_BETA_ARM_M)
    k1, k2, ast = p.value("k1"), p.value("k2"), p.value("alpha_star")
    bstar = k1 * ast / (k1 - k2)

    def g(ch, d):
        c0, c1, c2, c3 = coefs[ch]
        return jnp.where(d > 0, c0 + d * (c1 + d * (c2 + d * c3)), f0[ch])

    def bond(ch, xs, xo):
        L, d0 = levers[ch], d0s[ch]
        return p.band_scale * L * (g(ch, d0 + L * (xs - xo)) - g(ch, d0 - L * (xs - xo)))

    def rhs(t, y, pert):
        x, v = y[: 2 * n], y[2 * n :]
        parts = []
        for ch in range(2):
            xc = x[ch * n : (ch + 1) * n]
            right = band[ch] * bond(ch, xc[:-1], xc[1:])
            left = band[ch] * bond(ch, xc[1:], xc[:-1])
            parts.append(-jnp.concatenate([right, jnp.zeros(1)]) - jnp.concatenate([jnp.zeros(1), left]))
        F = jnp.concatenate(parts)
        a, b = x[:n], x[n:]
        psi = jnp.where(a < -bstar, k1 * (a + ast), jnp.where(a > bstar, k1 * (a - ast), k2 * a))
        kab, sig = p.value("k_ab"), p.value("sigma")
        F = F + jnp.concatenate([kab * (b - a) - psi - sig * b, kab * (a - b)]) + pert
        return jnp.concatenate([v, (F - eta * v) * inv_i])

    segs = _segments(scene, t_eval)
    perts = [jnp.asarray(_pert_vector(scene, n, a)) for a, _, _ in segs]
    points = []
    solvers = {name: getattr(diffrax, name)() for name in DIFFRAX_SOLVERS}

    def make_run(solver):
        """The whole restarted solve for one solver; rtol and atol are traced arguments (one compilation per
        solver and segment length, not per tolerance)."""

        @jax.jit
        def seg_solve(y, pert, t0, t1, ts, rtol, atol):
            sol = diffrax.diffeqsolve(
                diffrax.ODETerm(rhs),
                solver,
                t0,
                t1,
                None,
                y,
                args=pert,
                saveat=diffrax.SaveAt(ts=ts),
                stepsize_controller=diffrax.PIDController(rtol=rtol, atol=atol),
                max_steps=2_000_000,
            )
            return sol.ys, sol.stats["num_steps"], sol.stats["num_rejected_steps"]

        def run(rtol):
            y = jnp.asarray(y0)
            ys = [np.asarray(y0)]
            steps = rejected = 0
            for (a, b, te), pv in zip(segs, perts):
                out, ns, nr = seg_solve(y, pv, a, b, jnp.asarray(te), rtol, rtol * ATOL_FACTOR)
                out.block_until_ready()
                ys.extend(np.asarray(out))
                y = out[-1]
                steps += int(ns)
                rejected += int(nr)
            return np.array(ys), steps, rejected

        return run

    for name, solver in solvers.items():
        run = make_run(solver)
        compile_s = None
        for rtol in rtols(quick):
            if rtol < DIFFRAX_TIGHTEST.get(name, 0.0) * 0.99:
                continue
            try:
                t0 = clock()
                run(rtol)
                first = clock() - t0
                (y, steps, rej), w = median_time(partial(run, rtol), repeat=REPEAT, budget_s=3.0)
                err = max_err(y[:, : 2 * n], ref_x)
            except Exception as e:  # noqa: BLE001 - a failing peer is reported, not fatal
                log(f"  diffrax {name} rtol {rtol:g}: {type(e).__name__}: {str(e).splitlines()[0][:120]}")
                continue
            if compile_s is None:
                compile_s = max(first - w, 0.0)
                log(f"  diffrax {name}: compile {compile_s * 1e3:.0f} ms (first call minus a warm one)")
            points.append(
                WPPoint(
                    f"diffrax {name}",
                    f"rtol={rtol:g}",
                    w,
                    err,
                    extra={"steps": steps, "rejected": rej, "compile_s": compile_s},
                )
            )
    return points


# ---------------------------------------------------------------- CVODE
def cvode_points(
    scene: Scene,
    t_eval: np.ndarray,
    y0: np.ndarray,
    ref_x: np.ndarray,
    quick: bool = False,
    log: Callable[..., None] = print,
) -> list[WPPoint]:
    try:
        from sksundae.cvode import CVODE
    except ImportError as e:
        log(f"  CVODE: skipped ({e.name or e} not installed; pip install -e '.[bench]')")
        return []
    rhs = compiled_rhs(scene)
    n2 = 2 * scene.cells

    def f(t, y, yp):
        yp[:] = rhs(t, y)

    segs = _segments(scene, t_eval)

    def make_run(method, rtol):
        """The whole restarted solve for one method and tolerance (bound here, not from the loop)."""

        def run():
            y = np.asarray(y0, float)
            ys = [y]
            for a, _, te in segs:
                sol = CVODE(f, method=method, rtol=rtol, atol=rtol * ATOL_FACTOR, max_num_steps=10_000_000).solve(
                    np.concatenate([[a], te]), y
                )
                if not sol.success:
                    raise RuntimeError(sol.message)
                ys.extend(sol.y[1:])
                y = sol.y[-1]
            return np.array(ys)

        return run

    points = []
    for method in ("Adams", "BDF"):
        for rtol in rtols(quick):
            run = make_run(method, rtol)
            try:
                y, w = median_time(run, repeat=REPEAT, budget_s=2.0)
                err = max_err(y[:, :n2], ref_x)
            except Exception as e:  # noqa: BLE001
                log(f"  CVODE {method} rtol {rtol:g}: {type(e).__name__}: {str(e).splitlines()[0][:120]}")
                w, err = math.nan, math.inf
            points.append(WPPoint(f"CVODE {method}", f"rtol={rtol:g}", w, err))
    return points


def peer_points(
    scene: Scene,
    t_eval: np.ndarray,
    y0: np.ndarray,
    ref_x: np.ndarray,
    quick: bool = False,
    log: Callable[..., None] = print,
) -> list[WPPoint]:
    w0 = time.perf_counter()
    pts = diffrax_points(scene, t_eval, y0, ref_x, quick, log) + cvode_points(scene, t_eval, y0, ref_x, quick, log)
    log(f"  compiled peers: {len(pts)} points in {time.perf_counter() - w0:.1f} s")
    return pts
