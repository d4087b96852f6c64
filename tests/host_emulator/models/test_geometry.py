"""Beta chain: the full geometric band law agrees with the small-angle form at small angles."""

import numpy as np

from host_emulator.controller import run_solver
from host_emulator.models import ModelOptions, Perturbation
from host_emulator.models.lattice import LatticeModel
from host_emulator.params import Params


def beta_forces(geom, x):
    """Band torques on the beta cylinders alone (k_ab = 0 removes R_b)."""
    m = LatticeModel(Params(cells=6, k_ab=0.0), [], ModelOptions(beta_geometry=geom))
    return m.forces(0.0, x)[0][6:]


def test_geometric_matches_small_angle_to_second_order():
    rng = np.random.default_rng(2)
    shape = rng.standard_normal(12)
    rel = []
    for eps in (1e-2, 1e-3):
        x = eps * shape
        fs, fg = beta_forces("small", x), beta_forces("geometric", x)
        rel.append(np.abs(fg - fs).max() / np.abs(fs).max())
    assert rel[0] < 1e-3
    assert rel[0] / rel[1] > 30  # the difference vanishes like eps^2


def test_geometric_differs_for_large_common_rotation():
    """Sanity of the geometric form: arms turned by beta0 = 1 rad see a shorter stretch (stiffness about
    cos^2 beta0 = 0.29 of the small-angle one, plus a tension term): the end cylinder's torque is much smaller."""
    x = np.zeros(12)
    x[6:] = 1.0 + 1e-3 * np.arange(6)
    fs, fg = beta_forces("small", x), beta_forces("geometric", x)
    ratio = fg[0] / fs[0]
    assert 0.3 < ratio < 0.5


def test_small_perturbation_trajectories_agree():
    out = []
    for geom in ("small", "geometric"):
        m = LatticeModel(
            Params(cells=8, sigma=14 / 125, eta_scale=10),
            [Perturbation(4, "alpha", 5e-4, 0.0, 0.05)],
            ModelOptions(beta_geometry=geom),
        )
        out.append(run_solver(m.solver(), 0.5))
    a, b = out
    assert np.abs(a.beta).max() > 1e-3
    assert np.abs(a.beta - b.beta).max() < 1e-3 * np.abs(a.beta).max()
