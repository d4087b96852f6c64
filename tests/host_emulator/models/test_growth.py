"""Linear regime of the lattice: measured growth of a tiny perturbation vs the linear stability analysis."""

import numpy as np
import pytest

from host_emulator.models import ModelOptions
from host_emulator.models.lattice import LatticeModel
from host_emulator.params import Params

N = 16
J_CENTRES = np.arange(N) + 0.5


def mode_block(p, m, inertia):
    """Linearised dynamics of free-end mode m (cos(kappa (j - 1/2)), kappa = m pi / N), written from
    docs/physics.md#equations-of-motion."""
    q = 2 * (1 - np.cos(np.pi * m / N))
    A2 = np.array([[-p.k_ab - p.k2 - q * p.ka_eff, p.k_ab - p.sigma], [p.k_ab, -p.k_ab - q * p.kb_eff]])
    eta = np.array([p.eta_alpha, p.eta_beta])
    if not inertia:
        return A2 / eta[:, None]
    moi = np.array([p.I_a, p.I_b])
    return np.block([[np.zeros((2, 2)), np.eye(2)], [A2 / moi[:, None], -np.diag(eta / moi)]])


def measured_growth(p, m, inertia):
    """Start from a tiny random state; fit the growth of the alpha projection on mode m once it dominates."""
    rng = np.random.default_rng(5)
    x0 = 1e-9 * rng.standard_normal(2 * N)
    mod = LatticeModel(p, [], ModelOptions(bands="linear", inertia=inertia, stepper="rk4", dt_out=0.005))
    s = mod.solver(x0=x0)
    shape = np.cos(np.pi * m * J_CENTRES / N)
    t, c = [], []
    while s.t < 2.0 and np.abs(s.x).max() < 1e-4:  # stay linear: far below the psi' breakpoint
        s.advance()
        t.append(s.t)
        c.append(abs(shape @ s.x[:N]))
    t, c = np.array(t), np.array(c)
    sel = t > t[-1] - 0.25
    return np.polyfit(t[sel], np.log(c[sel]), 1)[0]


@pytest.mark.parametrize("sigma", [9 / 125, 6 / 125])
@pytest.mark.parametrize("inertia", [False, True])
def test_growth_rate_matches_linear_theory(sigma, inertia):
    p = Params(cells=N, sigma=sigma)
    rates = [np.linalg.eigvals(mode_block(p, m, inertia)).real.max() for m in range(N)]
    m = int(np.argmax(rates))
    got = measured_growth(p, m, inertia)
    assert rates[m] > 5
    assert got == pytest.approx(rates[m], rel=0.02)
    try:
        from host_emulator.analysis.stability import growth_rates
    except ImportError:
        pytest.skip("analysis.stability not available")
    theory = growth_rates(p, [np.pi * m / N], discrete=True, inertia=inertia)[0, 0].real
    assert got == pytest.approx(theory, rel=0.02)
