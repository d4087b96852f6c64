"""Compiled plant (C) against the independent numpy reference plant: forces and whole trajectories."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host_emulator.models import ModelOptions, NoiseOptions, Perturbation
from host_emulator.models.lattice import LatticeModel
from host_emulator.models.reference import ReferencePlant
from host_emulator.params import Params

COMBOS = [
    dict(bands="linear"),
    dict(bands="cubic"),
    dict(bands="cubic", beta_geometry="geometric"),
    dict(bands="cubic", inertia=False),
    dict(bands="cubic", noise=NoiseOptions(seed=3, band_spread=0.2, eta_spread=0.3)),
]


def _models(opts, slack_f0=True, n=7, perts=()):
    p = Params(cells=n, slack_f0=slack_f0)
    o = ModelOptions(**opts)
    return LatticeModel(p, list(perts), o), ReferencePlant(p, o, list(perts))


@pytest.mark.parametrize("opts", COMBOS)
@pytest.mark.parametrize("slack_f0", [True, False])
def test_forces_match_reference(opts, slack_f0):
    m, ref = _models(opts, slack_f0)
    rng = np.random.default_rng(1)
    for scale in (1e-3, 0.3, 1.2):  # 1.2 rad differences make alpha bands go slack
        x = scale * rng.standard_normal(2 * m.n)
        F, C = m.forces(0.0, x)
        Fr, Cr = ref.forces(0.0, x)
        np.testing.assert_allclose(F, Fr, rtol=1e-11, atol=1e-15)
        np.testing.assert_allclose(C, Cr, rtol=1e-14)


@settings(max_examples=60, deadline=None)
@given(st.lists(st.floats(-2.0, 2.0), min_size=10, max_size=10), st.booleans())
def test_forces_match_reference_property(xs, geometric):
    m, ref = _models(dict(beta_geometry="geometric" if geometric else "small"), n=5)
    x = np.array(xs)
    F, _ = m.forces(0.3, x)
    Fr, _ = ref.forces(0.3, x)
    np.testing.assert_allclose(F, Fr, rtol=1e-10, atol=1e-14)


def test_perturbation_window_matches_reference():
    perts = [Perturbation(2, "alpha", 0.01, 0.1, 0.2), Perturbation(4, "beta", -0.003, 0.0, 0.05)]
    m, ref = _models(dict(), perts=perts)
    x = np.zeros(2 * m.n)
    for t in (0.0, 0.049, 0.05, 0.1, 0.2, 0.2999, 0.3):
        np.testing.assert_array_equal(m.forces(t, x)[0], ref.forces(t, x)[0])
    assert m.forces(0.15, x)[0][1] == pytest.approx(0.01)


@pytest.mark.parametrize("stepper", ["symplectic_euler", "rk4", "euler"])
@pytest.mark.parametrize("inertia", [True, False])
def test_trajectories_match_reference(stepper, inertia):
    """0.5 s of a perturbed 6-cell lattice, same stepper and step: C and numpy agree to rounding."""
    perts = [Perturbation(3, "alpha", 0.02, 0.0, 0.05)]
    p = Params(cells=6, band_scale=0.5)  # the table stiffness keeps dt = 1e-4 inside every stepper's limit
    o = ModelOptions(stepper=stepper, inertia=inertia, dt_out=0.01, dt=1e-4)
    m = LatticeModel(p, perts, o)
    ref = ReferencePlant(p, o, perts)
    s = m.solver()
    traj = [s.state()[0]]
    for _ in range(50):
        s.advance()
        traj.append(s.state()[0])
    xs, _ = ref.run(stepper, s.h, 50 * s.nsub, record_every=s.nsub)
    assert np.abs(xs[-1, :6]).max() > 0.01  # it did move
    np.testing.assert_allclose(np.array(traj), xs[:, :6], rtol=1e-8, atol=1e-11)
