"""Passive lattice (sigma = k_ab = 0): the mechanical energy decreases at exactly the dissipated power."""

import numpy as np
import pytest

from host_emulator import params as P
from host_emulator.models import ModelOptions
from host_emulator.models.lattice import LatticeModel
from host_emulator.params import Params


def G(coef, d):
    """Antiderivative of the cubic band force, G(0) = 0 (no slack in these runs)."""
    c0, c1, c2, c3 = coef
    return d * (c0 + d * (c1 / 2 + d * (c2 / 3 + d * c3 / 4)))


def energy(p, bands, x, v, psi_k):
    n = p.cells
    a, b = x[:n], x[n:]
    E = 0.5 * p.I_a * (v[:n] ** 2).sum() + 0.5 * p.I_b * (v[n:] ** 2).sum() + 0.5 * psi_k * (a**2).sum()
    for u, coef, d0, L, k in (
        (np.diff(a), P.BAND_A_COEF, P.DELTA_A0_M, P.R_ALPHA_M, p.ka_eff),
        (np.diff(b), P.BAND_B_COEF, P.DELTA_B0_M, P.R_BETA_ARM_M, p.kb_eff),
    ):
        if bands == "linear":
            E += 0.5 * k * (u**2).sum()
        else:  # U(u) = s [G(d0 + L u) + G(d0 - L u) - 2 G(d0)]
            E += p.band_scale * (G(coef, d0 + L * u) + G(coef, d0 - L * u) - 2 * G(coef, d0)).sum()
    return E


@pytest.mark.parametrize("bands,psi_k", [("linear", 0.0), ("linear", 0.05), ("cubic", 0.0), ("cubic", 0.05)])
def test_energy_decays_at_dissipated_power(bands, psi_k):
    # psi off (k1 = k2 = 0) or linear (k1 = k2 = psi_k): psi'(x) = max(k|x|, k|x| - k a*) sign x = k x
    p = Params(cells=6, sigma=0.0, k_ab=0.0, k1=psi_k, k2=psi_k)
    h = 2e-5
    m = LatticeModel(p, [], ModelOptions(bands=bands, stepper="rk4", dt=h, dt_out=h))
    rng = np.random.default_rng(0)
    x0 = 0.15 * rng.standard_normal(12)  # small enough that no band goes slack
    s = m.solver(x0=x0)
    E = [energy(p, bands, s.x, s.v, psi_k)]
    C = m.forces(0.0, s.x)[1]
    P_diss = [(C * s.v**2).sum()]
    for _ in range(10000):  # 0.2 s
        s.advance()
        E.append(energy(p, bands, s.x, s.v, psi_k))
        P_diss.append((C * s.v**2).sum())
    E, P_diss = np.array(E), np.array(P_diss)
    dissipated = np.sum((P_diss[1:] + P_diss[:-1]) / 2) * h
    assert E[-1] < 0.2 * E[0]  # most of it is gone: a real test of the balance
    assert np.all(np.diff(E) <= 1e-12 * E[0])  # never increases
    np.testing.assert_allclose(E[0] - E[-1], dissipated, rtol=1e-5)
