"""Noh-Bathe and IMEX steppers: order against the exact linear solution, limits from an independent eigen-analysis,
trajectories against numpy transcriptions of their equations, use inside the hil loop."""

import numpy as np
import pytest
import scipy.linalg
from hypothesis import given, settings
from hypothesis import strategies as st

from host_emulator import firmware
from host_emulator.models import ModelOptions, Perturbation
from host_emulator.models.hil import HilModel
from host_emulator.models.lattice import LatticeModel
from host_emulator.models.reference import STAGE_EDGE, ReferencePlant
from host_emulator.params import Params
from tests.host_emulator.linear_lattice import linear_system

N = 5
P_NB = 0.54


def rel_error(stepper, dt, inertia=True, t_end=0.2, eta_scale=10):
    p = Params(cells=N, sigma=14 / 125, eta_scale=eta_scale)
    x0 = 1e-3 * np.sin(np.arange(2 * N) + 0.5)
    m = LatticeModel(p, [], ModelOptions(bands="linear", stepper=stepper, dt=dt, dt_out=t_end, inertia=inertia))
    s = m.solver(x0=x0)
    s.advance()
    y0 = np.r_[x0, np.zeros(2 * N)] if inertia else x0
    exact = scipy.linalg.expm(linear_system(p, inertia) * t_end) @ y0
    return np.abs(s.x - exact[: 2 * N]).max() / np.abs(x0).max()


@pytest.mark.parametrize(
    "stepper,order,dt,inertia",
    [
        ("noh_bathe", 2, 2.5e-5, True),
        ("noh_bathe", 2, 2e-4, False),
        ("imex_euler", 1, 1e-4, True),
        ("imex_euler", 1, 2e-4, False),
    ],
)
def test_convergence_order(stepper, order, dt, inertia):
    e1, e2 = rel_error(stepper, dt, inertia), rel_error(stepper, dt / 2, inertia)
    assert abs(np.log2(e1 / e2) - order) < 0.25, (e1, e2)


def nb_amplification(c, w2, h, p=P_NB):
    """Amplification matrix of Noh-Bathe on x'' = -w2 x - c x' for the carried state (x, v, a), written from
    the paper's equations independently of the C code."""
    q1 = (1 - 2 * p) / (2 * p * (1 - p))
    q2 = 0.5 - p * q1
    q0 = -q1 - q2 + 0.5
    s = (1 - p) * h
    A = np.zeros((3, 3))
    for j in range(3):
        x, v, a = np.eye(3)[j]
        xp = x + p * h * v + (p * h) ** 2 / 2 * a
        ap = -w2 * xp - c * (v + p * h * a)
        vp = v + p * h / 2 * (a + ap)
        x1 = xp + s * vp + s * s / 2 * ap
        a1 = -w2 * x1 - c * (vp + s * ap)
        A[:, j] = [x1, vp + s * (q0 * a + (0.5 + q1) * ap + q2 * a1), a1]
    return A


@settings(max_examples=60, deadline=None)
@given(st.floats(0.0, 3.0), st.floats(0.05, 4.0))
def test_noh_bathe_radius_matches_eigenvalues(ch, omega):
    """The C spectral radius (repeated squaring) equals numpy's eigenvalues of the amplification matrix."""
    _, lib = firmware.load()
    w2, h = 1.0, omega  # units with w = 1: Omega = w h, damping c h
    A = nb_amplification(ch / h, w2, h)
    rho = np.abs(np.linalg.eigvals(A)).max()
    assert lib.he_noh_bathe_radius(ch / h, w2, h) == pytest.approx(rho, rel=1e-6, abs=1e-9)


def test_noh_bathe_undamped_critical_step():
    """Undamped critical Omega from numpy eigenvalues (bisection) equals the C limit of a one-mode plant."""
    lo, hi = 1.0, 5.0
    for _ in range(60):
        mid = (lo + hi) / 2
        lo, hi = (
            (mid, hi) if np.abs(np.linalg.eigvals(nb_amplification(0.0, 1.0, mid))).max() <= 1 + 1e-9 else (lo, mid)
        )
    assert 2.0 < lo < 4.0  # Noh-Bathe's undamped limit exceeds central differences' 2 (per step)
    # a two-cell lattice, linear bands, no reaction, no damping: w2 bound = 4 k_a / I_a (Gershgorin), one chain
    ffi, lib = firmware.load()
    m = LatticeModel(
        Params(cells=2, eta_a=1e-30, k_ab=0.0, k1=0.0, k2=0.0, sigma=0.0, alpha_star=0.0),
        [],
        ModelOptions(bands="linear", stepper="noh_bathe"),
    )
    w2 = ffi.new("double[2]")
    cmn = ffi.new("double[2]")
    cmx = ffi.new("double[2]")
    r = ffi.new("double[2]")
    lib.he_plant_bounds(m.plant, w2, cmn, cmx, r)
    h, _ = m.step_limit()
    assert h * np.sqrt(max(w2[0], w2[1])) == pytest.approx(lo, rel=1e-5)


@pytest.mark.parametrize("stepper", ["noh_bathe", "imex_euler"])
@pytest.mark.parametrize("inertia", [True, False])
def test_limit_is_stable_and_beyond_blows_up(stepper, inertia):
    """0.9x the computed limit is stable on the stiffest linear lattice; 3x (5x for the IMEX, whose limit
    comes from a Gershgorin bound of the explicit reaction only) is not."""
    p = Params(cells=16, sigma=14 / 125, eta_scale=10, actuator_limit=False)  # the linear system, unclipped
    m = LatticeModel(p, [], ModelOptions(bands="linear", stepper=stepper, inertia=inertia))
    h, _ = m.step_limit()
    x0 = 1e-3 * np.cos(np.pi * np.arange(32))
    s = m.solver(x0=x0)
    rc = m.lib.he_advance(m.plant, s.sid, 0.9 * h, int(2.0 / h), s._pt, s._px, s._pv)
    assert rc == m.lib.HE_OK and np.abs(s.x).max() < 1e-2
    s2 = m.solver(x0=x0)
    k = 3.0 if stepper == "noh_bathe" else 5.0
    rc = m.lib.he_advance(m.plant, s2.sid, k * h, 20000, s2._pt, s2._px, s2._pv)
    assert rc in (m.lib.HE_ERR_NONFINITE, m.lib.HE_ERR_DIVERGED)


def numpy_noh_bathe(ref, h, nsteps, x, v):
    """Noh-Bathe (inertia) on the numpy reference plant, from the equations in he_noh_bathe.h."""
    p = P_NB
    q1 = (1 - 2 * p) / (2 * p * (1 - p))
    q2 = 0.5 - p * q1
    q0 = -q1 - q2 + 0.5
    s, ph, E = (1 - p) * h, p * h, STAGE_EDGE

    def acc(t, xx, vv):
        F, C = ref.forces(t, xx)
        return (F - C * vv) / ref.I

    a0 = acc(E * h, x, v)
    for k in range(nsteps):
        t = k * h
        xp = x + ph * v + ph * ph / 2 * a0
        ap = acc(t + ph, xp, v + ph * a0)
        vp = v + ph / 2 * (a0 + ap)
        x = xp + s * vp + s * s / 2 * ap
        a1 = acc(t + h - E * h, x, vp + s * ap)
        v = vp + s * (q0 * a0 + (0.5 + q1) * ap + q2 * a1)
        a0 = a1
        if any(t + h - E * h < e <= t + h + E * h for q in ref.perts for e in (q.start_s, q.start_s + q.duration_s)):
            a0 = acc(t + h + E * h, x, vp + s * ap)
    return x, v


def numpy_imex(ref, h, nsteps, x, v, inertia):
    """Linearly implicit Euler on the numpy plant; the band tangent stiffness by central differences of the
    numpy band torques (independent of the C derivative), one banded solve per chain."""
    n = ref.n
    for k in range(nsteps):
        F, C = ref.forces(k * h + STAGE_EDGE * h, x)
        Kb = np.zeros((2 * n, 2 * n))
        eps = 1e-7
        for i in range(2 * n):
            d = np.zeros(2 * n)
            d[i] = eps
            Kb[:, i] = -(ref.band_torques(x + d) - ref.band_torques(x - d)) / (2 * eps)
        if inertia:
            A = np.diag(ref.I + h * C) + h * h * Kb
            v = np.linalg.solve(A, ref.I * v + h * F)
        else:
            A = np.diag(C) + h * Kb
            v = np.linalg.solve(A, h * F) / h
        x = x + h * v
    return x, v


@pytest.mark.parametrize("stepper,inertia", [("noh_bathe", True), ("imex_euler", True), ("imex_euler", False)])
def test_trajectory_matches_numpy_transcription(stepper, inertia):
    """0.3 s of a perturbed 6-cell lattice with cubic bands: C and the numpy transcription agree."""
    perts = [Perturbation(3, "alpha", 0.02, 0.0, 0.05), Perturbation(5, "beta", -0.004, 0.1, 0.05)]
    p = Params(cells=6)
    o = ModelOptions(stepper=stepper, inertia=inertia, dt=2.5e-4, dt_out=0.3)
    m = LatticeModel(p, perts, o)
    ref = ReferencePlant(p, o, perts)
    s = m.solver()
    s.advance()
    h = s.h
    x, v = (
        numpy_noh_bathe(ref, h, s.nsub, np.zeros(12), np.zeros(12))
        if stepper == "noh_bathe"
        else numpy_imex(ref, h, s.nsub, np.zeros(12), np.zeros(12), inertia)
    )
    assert np.abs(x).max() > 0.05  # something happened
    assert np.abs(s.x - x).max() < (1e-10 if stepper == "noh_bathe" else 1e-7)


def test_registry_and_clear_errors():
    from host_emulator.models.steppers import STEPPERS

    assert {"noh_bathe", "imex_euler"} <= set(STEPPERS)
    m = LatticeModel(Params(cells=8), [], ModelOptions(stepper="noh_bathe", dt=0.05))
    lim, chain = m.step_limit()
    with pytest.raises(ValueError, match=r"exceeds the stable step limit .* stepper 'noh_bathe'") as e:
        m.solver()
    assert f"{lim:.4g}" in str(e.value) and chain in str(e.value)


@pytest.mark.parametrize("stepper", ["noh_bathe", "imex_euler"])
def test_hil_loop_runs_the_new_steppers(stepper):
    """The compiled hil loop uses he_advance, so it takes the new steppers: 0.5 s of the pushed default rig
    stays within 3 encoder counts of the same loop with rk4 at 8 plant steps per tick."""
    perts = [Perturbation(8, "alpha", 0.02, 0.1, 0.1)]
    p = Params(cells=16, bemf_comp=False)

    def run(st, sub):
        s = HilModel(p, perts, ModelOptions(stepper=st, substeps=sub)).solver()
        for _ in range(50):
            s.advance()
        return s.x.copy()

    ref = run("rk4", 8)
    got = run(stepper, 2)
    assert np.abs(ref).max() > 0.3
    assert np.abs(got - ref).max() < 3 * 2 * np.pi / 400
