"""Reference plant in numpy, from docs/physics.md#equations-of-motion (vectorised, no code shared with the C plant).

The band and reaction laws are physics.py's (the one Python copy, checked against an independent float
reference in tests/host_emulator/test_physics.py); the assembly, geometry and stepping here are independent.

Used by the tests to check the compiled plant (forces and whole trajectories) and as executable
documentation of the equations. Same conventions: x = [alpha_1..alpha_n, beta_1..beta_n],
I x'' = F(t, x) - C x'  (or C x' = F when overdamped).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from .. import params as P
from ..params import Params
from ..physics import band_force, reaction
from .options import ModelOptions, Perturbation
from .plant import spreads

STAGE_EDGE = 1e-9  # = HE_STAGE_EDGE: stages at a step's ends are evaluated at t + e h, t + (1 - e) h


class ReferencePlant:
    def __init__(
        self,
        params: Params,
        options: ModelOptions | None = None,
        perturbations: Sequence[Perturbation] = (),
        *,
        ideal_reaction: bool = True,
    ) -> None:
        self.p = params
        self.o = options or ModelOptions()
        self.n = params.cells
        self.perts = list(perturbations)
        self.ideal = ideal_reaction
        band, eta = spreads(params, self.o, self.n)
        topo = params.topology
        # bonds (i, k), 0-based: None for the open chain (its (j, j+1) bonds, written out below), else the
        # topology's edge list (a ring, a sheet), one band factor per bond
        self.bonds = None if topo.is_open_chain else np.asarray(topo.bonds, dtype=np.intp)
        self.band = band[:, : self.n - 1] if self.bonds is None else band
        self.eta = np.concatenate([params.eta_alpha * eta[0], params.eta_beta * eta[1]])
        self.I = np.concatenate([np.full(self.n, params.I_a), np.full(self.n, params.I_b)])

    # ---- band law -------------------------------------------------------
    def _g(self, coef, d):
        """Slack rule: f(d) for d > 0, else f(0) (slack_f0) or 0."""
        f0 = coef[0] if self.p.slack_f0 else 0.0
        return np.where(d > 0, band_force(coef, d), f0)

    def bond_torque(self, chain: int, xs: np.ndarray, xo: np.ndarray) -> np.ndarray:
        """tau(x_self, x_other) of docs/physics.md#band-torque for arrays of bonds (before the per-bond spread)."""
        if self.o.bands == "linear":
            return (self.p.ka_eff, self.p.kb_eff)[chain] * (xs - xo)
        coef = (P.BAND_A_COEF, P.BAND_B_COEF)[chain]
        d0 = (P.DELTA_A0_M, P.DELTA_B0_M)[chain]
        if chain == 0:
            L = P.R_ALPHA_M
            dp, dm = d0 + L * (xs - xo), d0 - L * (xs - xo)
            return self.p.band_scale * L * (self._g(coef, dp) - self._g(coef, dm))
        L = P.R_BETA_ARM_M
        if self.o.beta_geometry == "small":
            dp, dm = d0 + L * (xs - xo), d0 - L * (xs - xo)
            return self.p.band_scale * L * (self._g(coef, dp) - self._g(coef, dm))
        a = P.LATTICE_M
        ds = np.sin(xs) - np.sin(xo)
        dc = np.cos(xs) - np.cos(xo)
        total = np.zeros_like(ds)
        for sgn in (+1.0, -1.0):
            Delta = np.hypot(a + sgn * L * ds, -sgn * L * dc) - a
            fT = self._g(coef, d0 + Delta) * (np.cos(xs) * (a + sgn * L * ds) - sgn * L * np.sin(xs) * dc) / (a + Delta)
            total = total + sgn * fT
        return self.p.band_scale * L * total

    def band_torques(self, x: np.ndarray) -> np.ndarray:
        """Net band torque on every cylinder: -tau(x_j, x_{j-1}) - tau(x_j, x_{j+1}), free ends (the open chain);
        on any other topology -sum over the bonds (i, k) at a cell of tau(x_self, x_other), each bond seen from
        both of its cells (np.add.at sums the bonds at a cell)."""
        n = self.n
        out = np.zeros(2 * n)
        if self.bonds is not None:
            i, k = self.bonds[:, 0], self.bonds[:, 1]
            for ch in range(2):
                xc = x[ch * n : (ch + 1) * n]
                o = out[ch * n : (ch + 1) * n]
                np.add.at(o, i, -self.band[ch] * self.bond_torque(ch, xc[i], xc[k]))  # on i from k
                np.add.at(o, k, -self.band[ch] * self.bond_torque(ch, xc[k], xc[i]))  # on k from i
            return out
        for ch in range(2):
            xc = x[ch * n : (ch + 1) * n]
            right = self.band[ch] * self.bond_torque(ch, xc[:-1], xc[1:])  # on j from j+1
            left = self.band[ch] * self.bond_torque(ch, xc[1:], xc[:-1])  # on j+1 from j
            o = out[ch * n : (ch + 1) * n]
            o[:-1] -= right
            o[1:] -= left
        return out

    def forces(
        self, t: float, x: np.ndarray, volt: np.ndarray | None = None, mgain: np.ndarray | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        n = self.n
        F = self.band_torques(x)
        C = self.eta.copy()
        if self.ideal:
            a, b = x[:n], x[n:]
            lim = self.p.torque_limit_nm  # actuator limit (inf when off)
            ra, rb = reaction(self.p, a, b)  # physics.py
            F[:n] += np.clip(ra, -lim, lim)
            F[n:] += np.clip(rb, -lim, lim)
        if mgain is not None:
            F += mgain * volt
            C += mgain / self.p.speed_const
        for q in self.perts:
            if q.start_s <= t < q.start_s + q.duration_s:
                F[(0 if q.chain == "alpha" else n) + q.cell - 1] += q.torque_Nm
        return F, C

    # ---- steppers (numpy mirrors of the registered ones) ------------------
    def step(self, stepper: str, t: float, x: np.ndarray, v: np.ndarray, h: float) -> tuple[np.ndarray, np.ndarray]:
        E = STAGE_EDGE  # end stages just inside the step (he_step.h HE_STAGE_EDGE)
        if not self.o.inertia:

            def f(tt, xx):
                F, C = self.forces(tt, xx)
                return F / C

            if stepper == "rk4":
                k1 = f(t + E * h, x)
                k2 = f(t + h / 2, x + h / 2 * k1)
                k3 = f(t + h / 2, x + h / 2 * k2)
                k4 = f(t + h - E * h, x + h * k3)
                return x + h / 6 * (k1 + 2 * k2 + 2 * k3 + k4), (k1 + 2 * k2 + 2 * k3 + k4) / 6
            vv = f(t + E * h, x)
            return x + h * vv, vv
        if stepper == "symplectic_euler":
            F, C = self.forces(t + E * h, x)
            v1 = (v + h * F / self.I) / (1 + h * C / self.I)
            return x + h * v1, v1
        if stepper == "euler":
            F, C = self.forces(t + E * h, x)
            return x + h * v, v + h * (F - C * v) / self.I

        def g(tt, xx, vv):
            F, C = self.forces(tt, xx)
            return vv, (F - C * vv) / self.I

        a1, b1 = g(t + E * h, x, v)
        a2, b2 = g(t + h / 2, x + h / 2 * a1, v + h / 2 * b1)
        a3, b3 = g(t + h / 2, x + h / 2 * a2, v + h / 2 * b2)
        a4, b4 = g(t + h - E * h, x + h * a3, v + h * b3)
        return x + h / 6 * (a1 + 2 * a2 + 2 * a3 + a4), v + h / 6 * (b1 + 2 * b2 + 2 * b3 + b4)

    def run(
        self,
        stepper: str,
        h: float,
        nsteps: int,
        x0: ArrayLike | None = None,
        v0: ArrayLike | None = None,
        record_every: int = 1,
    ) -> tuple[np.ndarray, np.ndarray]:
        x = np.zeros(2 * self.n) if x0 is None else np.array(x0, float)
        v = np.zeros(2 * self.n) if v0 is None else np.array(v0, float)
        xs = [x.copy()]
        for s in range(nsteps):
            x, v = self.step(stepper, s * h, x, v, h)
            if (s + 1) % record_every == 0:
                xs.append(x.copy())
        return np.array(xs), v
