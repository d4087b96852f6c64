"""Steppers: convergence order against the exact linear solution (expm), stable-step limits, clear errors."""

import numpy as np
import pytest
import scipy.linalg

from host_emulator.models import ModelOptions, NumericalInstability
from host_emulator.models.lattice import LatticeModel
from host_emulator.params import Params
from tests.host_emulator.linear_lattice import linear_system

N = 5


def error_at(stepper, dt, t_end=0.2, eta_scale=10):
    p = Params(cells=N, sigma=14 / 125, eta_scale=eta_scale)
    x0 = 1e-3 * np.sin(np.arange(2 * N) + 0.5)
    m = LatticeModel(p, [], ModelOptions(bands="linear", stepper=stepper, dt=dt, dt_out=t_end))
    s = m.solver(x0=x0)
    s.advance()
    exact = scipy.linalg.expm(linear_system(p) * t_end) @ np.r_[x0, np.zeros(2 * N)]
    return np.abs(s.x - exact[: 2 * N]).max() / np.abs(x0).max()


@pytest.mark.parametrize(
    "stepper,order,dt,eta_scale", [("symplectic_euler", 1, 2e-4, 10), ("euler", 1, 2e-4, 10), ("rk4", 4, 2e-3, 1)]
)
def test_convergence_order(stepper, order, dt, eta_scale):
    e1 = error_at(stepper, dt, eta_scale=eta_scale)
    e2 = error_at(stepper, dt / 2, eta_scale=eta_scale)
    measured = np.log2(e1 / e2)
    assert abs(measured - order) < 0.3, (e1, e2, measured)


def test_too_large_dt_is_refused_naming_the_limit():
    m = LatticeModel(Params(cells=8), [], ModelOptions(dt=0.05))
    limit, chain = m.step_limit()
    with pytest.raises(ValueError, match=r"exceeds the stable step limit .* stepper 'symplectic_euler'") as e:
        m.solver()
    assert f"{limit:.4g}" in str(e.value) and chain in str(e.value)


@pytest.mark.parametrize("stepper", ["symplectic_euler", "rk4", "euler"])
@pytest.mark.parametrize("inertia", [True, False])
def test_limit_is_stable_and_3x_limit_blows_up(stepper, inertia):
    """The computed limit is honest: 0.9x is stable on the stiffest (linear, damped) lattice, 3x is not."""
    p = Params(cells=16, sigma=14 / 125, eta_scale=10)
    m = LatticeModel(p, [], ModelOptions(bands="linear", stepper=stepper, inertia=inertia))
    h, _ = m.step_limit()
    x0 = 1e-3 * np.cos(np.pi * np.arange(32))  # zig-zag: the stiffest modes
    s = m.solver(x0=x0)
    n = int(2.0 / h)
    rc = m.lib.he_advance(m.plant, s.sid, 0.9 * h, n, s._pt, s._px, s._pv)
    assert rc == m.lib.HE_OK and np.abs(s.x).max() < 1e-2
    s2 = m.solver(x0=x0)
    rc = m.lib.he_advance(m.plant, s2.sid, 3.0 * h, 20000, s2._pt, s2._px, s2._pv)
    assert rc in (m.lib.HE_ERR_NONFINITE, m.lib.HE_ERR_DIVERGED)


def test_unstable_run_stops_with_clear_error():
    """sigma = 14/125 with inertia at eta x1: the uniform mode is oscillatory-unstable; with cubic bands the
    growth is stopped when a band leaves the fit's range, never a silent NaN (without the actuator limit,
    which would bound it)."""
    m = LatticeModel(Params(cells=16, sigma=14 / 125, actuator_limit=False), [], ModelOptions())
    s = m.solver(x0=np.full(32, 1e-3))
    with pytest.raises(NumericalInstability, match="band stretched beyond|diverged"):
        for _ in range(1000):
            s.advance()
    assert s.t < 10


@pytest.mark.parametrize("stepper", ["euler", "symplectic_euler", "rk4", "noh_bathe", "imex_euler"])
def test_scratch_from_the_plant_or_per_call_gives_the_same_bits(stepper):
    """he_advance uses the plant's scratch (allocated once per model) or, without it, mallocs per call:
    both give the same trajectory to the bit, and the scratch is large enough for every stepper."""
    p = Params(cells=7)
    opts = ModelOptions(stepper=stepper, bands="cubic", inertia=True)
    perts = []
    a, b = LatticeModel(p, perts, opts), LatticeModel(p, perts, opts)
    assert a.plant.work_len == a.lib.HE_WORK_PER_STATE * 2 * a.n
    b.plant.work = a.ffi.NULL
    b.plant.work_len = 0
    x0 = np.r_[np.linspace(-0.3, 0.4, 7), np.linspace(0.2, -0.1, 7)]
    sa, sb = a.solver(x0=x0), b.solver(x0=x0)
    for _ in range(20):
        sa.advance()
        sb.advance()
    assert np.array_equal(sa.x, sb.x) and np.array_equal(sa.v, sb.v)
    assert np.abs(sa.x - x0).max() > 1e-6  # it moved
