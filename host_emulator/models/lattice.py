"""Lattice model (docs/physics.md#equations-of-motion): discrete equations of motion with the ideal floating-point
reaction, stepped in C."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from .. import firmware
from ..params import Params
from .options import DEFAULT_TOL, ModelOptions, Perturbation
from .plant import NumericalInstability, build_plant, choose_step, error_text, step_limit
from .solver import Solver
from .steppers import STEPPERS, stepper_id


class LatticeModel:
    """Physics only: the rate function of docs/physics.md#equations-of-motion (bands, honey, ideal R, perturbations).

    Switches (ModelOptions): inertia on/off, bands cubic/linear, beta small/geometric.
    ``forces(t, x)`` returns (F, C) with I x'' = F - C x' (or C x' = F when overdamped).
    """

    name = "lattice"
    ideal_reaction = True

    def __init__(
        self, params: Params, perturbations: Sequence[Perturbation] = (), options: ModelOptions | None = None
    ) -> None:
        self.params = params
        self.n = params.cells
        self.options = options or ModelOptions()
        self.perturbations = list(perturbations)
        self.ffi, self.lib = firmware.load()
        self.plant = build_plant(
            self.ffi, self.lib, params, self.options, self.n, self.perturbations, ideal_reaction=self.ideal_reaction
        )

    def forces(self, t: float, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x = np.ascontiguousarray(x, dtype=float)
        if x.shape != (2 * self.n,):
            raise ValueError(f"state must have shape ({2 * self.n},), got {x.shape}")
        F = np.empty(2 * self.n)
        C = np.empty(2 * self.n)
        ffi = self.ffi
        self.lib.he_plant_forces(
            self.plant,
            float(t),
            ffi.from_buffer("double[]", x),
            ffi.from_buffer("double[]", F),
            ffi.from_buffer("double[]", C),
        )
        return F, C

    def step_limit(self, stepper: str | None = None) -> tuple[float, str]:
        sid = stepper_id(self.lib, stepper or self.options.stepper)
        return step_limit(self.ffi, self.lib, self.plant, sid)

    def solver(self, x0: ArrayLike | None = None, v0: ArrayLike | None = None) -> LatticeSolver:
        return LatticeSolver(self, x0, v0)


class LatticeSolver(Solver):
    """Advances a LatticeModel one output interval at a time with the chosen compiled stepper: fixed steps (the
    largest step h <= model_options.dt that divides the output interval), or, for an adaptive stepper (dop853),
    error-controlled steps at model_options.tol with model_options.dt as the largest step (he_dop853.h)."""

    model: LatticeModel

    def __init__(self, model: LatticeModel, x0: ArrayLike | None = None, v0: ArrayLike | None = None) -> None:
        self.model = model
        opt = model.options
        self.stepper = opt.stepper
        self.sid = stepper_id(model.lib, opt.stepper)
        self.limit, self.limit_chain = model.step_limit()
        self.dt_out = opt.dt_out
        self.adaptive = STEPPERS[opt.stepper].adaptive
        self.tol: float | None
        ffi, lib = model.ffi, model.lib
        if self.adaptive:
            self.tol = opt.tol if opt.tol is not None else DEFAULT_TOL
            self.h, self.nsub = (opt.dt if opt.dt is not None else math.inf), 0  # largest step; steps vary
            n2 = 2 * model.n
            self._work = ffi.new("double[]", lib.HE_DOP853_WORK_PER_STATE * n2)
            self._ad = ffi.new("he_dop853_t *")
            # one tolerance for angles (rad) and speeds (rad/s), relative and absolute (he_dop853.h)
            rc = lib.he_dop853_init(self._ad, self.tol, self.tol, self.h, self._work, lib.HE_DOP853_WORK_PER_STATE * n2)
            if rc != lib.HE_OK:
                raise ValueError(f"model_options.tol = {self.tol!r}, dt = {opt.dt!r}: rejected by the adaptive stepper")
        else:
            self.tol = None
            self.h, self.nsub = choose_step(self.limit, self.dt_out, opt.dt, opt.stepper, self.limit_chain)
        n2 = 2 * model.n
        self.x = np.zeros(n2) if x0 is None else np.array(x0, dtype=float).reshape(n2)
        self.v = np.zeros(n2) if v0 is None else np.array(v0, dtype=float).reshape(n2)
        self.t = 0.0
        self.k = 0
        self._px = ffi.from_buffer("double[]", self.x)
        self._pv = ffi.from_buffer("double[]", self.v)
        self._pt = ffi.new("double *", 0.0)

    def info(self) -> dict:
        if self.adaptive:
            a = self._ad
            return {
                "stepper": self.stepper,
                "tol": self.tol,
                "dt_max_s": self.h,
                "steps": int(a.steps),
                "rejected_steps": int(a.rejects),
                "switch_landings": int(a.landings),
                "force_evaluations": int(a.nfev),
                "last_step_s": float(a.h),
                "stable_step_limit_s": self.limit,
                "limit_chain": self.limit_chain,
                "dt_out_s": self.dt_out,
            }
        return {
            "stepper": self.stepper,
            "dt_s": self.h,
            "steps_per_sample": self.nsub,
            "stable_step_limit_s": self.limit,
            "limit_chain": self.limit_chain,
            "dt_out_s": self.dt_out,
        }

    def plant_step_s(self) -> float | None:
        """The fixed step; for the adaptive stepper, the step it can hold over a run: the smaller of model_options.dt
        and the stable limit (an explicit method's error control keeps its steps near it where it binds, and takes
        smaller ones where accuracy needs them), so limits.check_solver judges an estimate of the cost, not a bound:
        enough to refuse a tiny inertia's run before it starts (None when neither bounds the step)."""
        if self.adaptive:
            h = min(float(self.h), float(self.limit))
            return h if math.isfinite(h) else None
        return float(self.h)

    def state(self) -> tuple[np.ndarray, np.ndarray]:
        n = self.model.n
        return self.x[:n].copy(), self.x[n:].copy()

    def _raise(self, rc, t, samples=None):
        if self.adaptive:
            how = f"stepper {self.stepper}, tol {self.tol:g}, last step {float(self._ad.h):.3g} s"
            fix = "else numerically: tighten model_options.tol or cap model_options.dt"
        else:
            how = f"stepper {self.stepper}, step {self.h:.3g} s, stable limit {self.limit:.3g} s"
            fix = "else numerically: reduce model_options.dt"
        err = NumericalInstability(
            f"{self.model.name}: {error_text(self.model.lib, rc)} at t = {t:.6g} s ({how}); "
            "the run is unstable (physically, if the linear analysis predicts growth for these parameters, "
            f"{fix})"
        )
        err.samples = samples
        raise err

    def _sampled(self, k0, k_max, buf, done):
        m = self.model
        if self.adaptive:
            return m.lib.he_dop853_sampled(
                m.plant,
                self._ad,
                self.dt_out,
                k0,
                k_max,
                self._pt,
                self._px,
                self._pv,
                m.ffi.from_buffer("double[]", buf),
                done,
            )
        return m.lib.he_advance_sampled(
            m.plant,
            self.sid,
            self.h,
            self.nsub,
            self.dt_out,
            k0,
            k_max,
            self._pt,
            self._px,
            self._pv,
            m.ffi.from_buffer("double[]", buf),
            done,
        )

    def advance(self) -> None:
        """One output interval."""
        if self.adaptive:
            self.advance_many(1)
            return
        self.k += 1
        self._pt[0] = (self.k - 1) * self.dt_out
        rc = self.model.lib.he_advance(self.model.plant, self.sid, self.h, self.nsub, self._pt, self._px, self._pv)
        if rc != self.model.lib.HE_OK:
            self._raise(rc, self._pt[0])
        self.t = self.k * self.dt_out

    def advance_many(self, k_max: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Up to k_max output intervals in one C call (he_advance_sampled, he_dop853_sampled), bit-identical to
        k_max advance() calls.

        Returns (t (k,), alpha (k, n), beta (k, n)) of the samples done. On an unstable run raises
        NumericalInstability (same message and time as advance()) whose ``samples`` holds the samples completed
        before the failing one, in the same form.
        """
        k_max = int(k_max)
        if k_max < 1:
            raise ValueError(f"k_max = {k_max}: must be >= 1")
        m = self.model
        n = m.n
        buf = np.empty((k_max, 2 * n))
        done = m.ffi.new("int64_t *", 0)
        k0 = self.k
        rc = self._sampled(k0, k_max, buf, done)
        k = int(done[0])
        t = np.arange(k0 + 1, k0 + k + 1) * self.dt_out  # k dt_out, as advance() computes it
        out = (t, buf[:k, :n], buf[:k, n:])
        if rc != m.lib.HE_OK:
            self.k = k0 + k + 1
            if k:
                self.t = float(t[-1])
            self._raise(rc, self._pt[0], out)
        self.k = k0 + k
        self.t = self.k * self.dt_out
        return out
