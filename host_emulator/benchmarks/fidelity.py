"""Fidelity cost (`bench --fidelity`): each model component switched to its cheaper/idealised variant, its wall time
and its effect on the observables (pattern period, amplitude, oscillation period, steady state).

Two questions, two scenes, 16 cells, 10 s simulated:
  * pattern   - experiment 3 (docs/physics.md#experiments) at sigma 9/125 (push on alpha_8): which pattern,
                which period, which amplitude;
  * stability - sigma 14/125, eta x1, a 50 mrad (3 encoder counts) uniform tilt of the alpha chain: does the
                long-wave mode oscillate/grow or decay
                (the inertial oscillation of docs/emulator.md), and at which period.
Reference row of each scene: the most faithful rig model (hil, rk4 x4 plant steps per tick, geometric beta,
cubic bands, inertia, 2 kHz, pwm_top 2400, back-EMF uncompensated as in the source build, no noise).
Every other row changes ONE component. Differences are against that reference.
"""

from __future__ import annotations

import argparse
import math
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..analysis.observables import observables
from ..controller import build_solver, run_solver
from ..models.hil import HilSolver
from ..models.options import NoiseOptions
from ..scene import load_scene
from .common import best_time, fmt, table

if TYPE_CHECKING:
    from ..scene import Scene

TILT_RAD = 0.05


def _base(question):
    if question == "pattern":
        sc = load_scene("default", ["t_end_s=10"])
    else:
        sc = load_scene("default", ["t_end_s=10", "params.sigma=14/125"])
    opts = replace(sc.options, stepper="rk4", substeps=4, beta_geometry="geometric", dt=None)
    return replace(sc, options=opts)


def variants(question: str) -> list[tuple[str, str, Scene]]:
    """(component, variant label, scene) rows; the first is the reference."""
    b = _base(question)
    P = b.params
    o = b.options

    def sc(model=None, params=None, **opt):
        return replace(b, model=model or b.model, params=params or P, options=replace(o, **opt))

    lat = dict(stepper="rk4", substeps=None, dt=None)
    rows = [
        ("reference", "hil rk4 x4, geometric beta, cubic, 2 kHz", b),
        (
            "plant step",
            "hil symplectic_euler x1 (accuracy fast = balanced)",
            sc(stepper="symplectic_euler", substeps=1),
        ),
        ("plant step", "hil rk4 x1", sc(substeps=1)),
        ("geometric beta", "small-angle beta bands", sc(beta_geometry="small")),
        ("non-linear bands", "linear bands (table k)", sc(bands="linear", beta_geometry="small")),
        (
            "inertia",
            "overdamped plant (no inertia; imex_euler x1, the explicit steppers need ~1 us steps)",
            sc(inertia=False, stepper="imex_euler", substeps=1),
        ),
        (
            "motor model",
            "lattice: ideal reaction torque, no motor/driver/encoder",
            sc("lattice", params=P.with_overrides(eta_a=P.eta_a), **lat),
        ),
        (
            "motor model",
            "lattice + motor back-EMF damping as extra eta",
            sc(
                "lattice",
                params=P.with_overrides(
                    eta_a=P.eta_a + P.eta_bemf, gamma=(P.eta_a * P.gamma + P.eta_bemf) / (P.eta_a + P.eta_bemf)
                ),
                **lat,
            ),
        ),
        ("PWM quantisation", "pwm_top 255 (analogWrite 8 bit)", sc(params=P.with_overrides(pwm_top=255))),
        ("PWM quantisation", "pwm_top 4095", sc(params=P.with_overrides(pwm_top=4095))),
        (
            "control rate",
            "500 Hz (plant step kept: 16 per tick)",
            sc(params=P.with_overrides(control_rate_hz=500.0), substeps=16),
        ),
        (
            "control rate",
            "20 kHz (plant step kept: 1 per tick)",
            sc(params=P.with_overrides(control_rate_hz=20000.0), substeps=1),
        ),
        ("back-EMF compensation", "firmware compensates back-EMF", sc(params=P.with_overrides(bemf_comp=True))),
        (
            "noise",
            "encoder jitter 0.3 counts + glitches 1e-4",
            sc(noise=NoiseOptions(seed=1, encoder_jitter_counts=0.3, encoder_glitch_prob=1e-4)),
        ),
        ("noise", "band and honey spread 5 %", sc(noise=NoiseOptions(seed=1, band_spread=0.05, eta_spread=0.05))),
    ]
    return rows


def _x0(question, n):
    return None if question == "pattern" else np.r_[np.full(n, TILT_RAD), np.zeros(n)]


def run_one(scene: Scene, question: str) -> tuple[dict | None, float, str]:
    def go():
        perts = scene.perturbations if question == "pattern" else []
        x0 = None if scene.model == "hil" else _x0(question, scene.cells)
        s = build_solver(scene, resolve=False, perturbations=perts, x0=x0)
        if question != "pattern" and scene.model == "hil":
            if not isinstance(s, HilSolver):
                raise TypeError(f"model hil built a {type(s).__name__}")
            # the same tilt after the encoders' zero (the firmware sees it as a real deflection)
            s.x[: scene.cells] = TILT_RAD
        return run_solver(s, scene.t_end_s)

    try:
        res, w = best_time(go, repeat=2, budget_s=3.0)
    except Exception as e:  # an unstable variant is a result too
        return (
            None,
            math.nan,
            "unstable: "
            + ("diverged" if "diverg" in str(e) else "band range" if "band" in str(e) else type(e).__name__),
        )
    return observables(res.t, res.alpha, res.beta), w, ""


def run_fidelity(args: argparse.Namespace, out: Path) -> int:
    for question in ("pattern", "stability"):
        rows = []
        ref = None
        for comp, label, scene in variants(question):
            obs, w, err = run_one(scene, question)
            if obs is None:
                rows.append([comp, label, fmt(w * 1e3), "-", "-", "-", "-", err])
                continue
            fa = np.asarray(obs["final_alpha_rad"])
            if ref is None:
                ref = (obs, fa)
            d = float(np.max(np.abs(fa - ref[1])))
            rows.append(
                [
                    comp,
                    label,
                    fmt(w * 1e3),
                    fmt(obs["pattern_period_cells"]),
                    fmt(obs["amplitude_rad"]),
                    fmt(obs["oscillation_period_s"]),
                    str(obs["steady"]),
                    fmt(d, 2),
                ]
            )
        setup = "exp. 3 push, sigma 9/125" if question == "pattern" else "sigma 14/125, 50 mrad uniform tilt"
        print(f"\n== fidelity, question '{question}' ({setup}), 16 cells, 10 s ==")
        print(
            table(
                rows,
                [
                    "component",
                    "variant",
                    "cpu ms",
                    "pattern period cells",
                    "amplitude rad",
                    "oscillation period s",
                    "steady",
                    "max |final alpha - ref| rad",
                ],
            )
        )
    return 0
