"""The chain's linear theory (analysis.chain): the whole lattice's Jacobian against the compiled forces, and its
reduction to the dispersion relation when every cell has the same law."""

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host_emulator.analysis import chain
from host_emulator.analysis.stability import Theory, growth_rates, motor_damping, theory_of
from host_emulator.analysis.summary import dispersion_summary
from host_emulator.models import ModelOptions, make_model
from host_emulator.params import Params


def _match(a: np.ndarray, b: np.ndarray) -> float:
    """Largest distance between two multisets of complex numbers, paired by optimal assignment."""
    from scipy.optimize import linear_sum_assignment

    d = np.abs(a[:, None] - b[None, :])
    r, c = linear_sum_assignment(d)
    return float(d[r, c].max())


@settings(max_examples=40, deadline=None)
@given(
    sigma=st.floats(0.0, 0.2),
    kab=st.floats(0.005, 0.06),
    k2=st.floats(-0.12, 0.02),
    n=st.integers(2, 12),
    inertia=st.booleans(),
    damped=st.booleans(),
)
def test_uniform_chain_is_the_dispersion_at_the_free_end_modes(sigma, kab, k2, n, inertia, damped):
    p = Params(cells=n, sigma=sigma, k_ab=kab, k2=k2)
    th = Theory("hil" if damped else "lattice", inertia, True, motor_damping(p) if damped else 0.0)
    got = chain.chain_modes(p, th)["growth_per_s"]
    km = np.pi * np.arange(n) / n
    want = growth_rates(p, km, inertia=inertia, motor_damping=th.motor_damping).ravel()
    scale = max(1.0, float(np.abs(want).max()))
    assert _match(got, want) <= 1e-8 * scale


def test_per_cell_values_that_agree_reduce_to_todays_dispersion():
    p = Params(sigma=0.072)
    same = Params(sigma=(0.072,) * 16, k2=(-0.06,) * 16)
    th = theory_of("hil", p)
    assert not same.heterogeneous
    assert dispersion_summary(same, th, 16) == dispersion_summary(p, th, 16)


def test_chain_jacobian_is_the_compiled_lattice_linearised():
    """A and E against central differences of the compiled lattice forces (linear bands, per-cell law), an
    independent assembly of the same equations."""
    rng = np.random.default_rng(4)
    n = 7
    p = Params(
        cells=n,
        sigma=tuple(rng.uniform(0.0, 0.15, n)),
        k_ab=tuple(rng.uniform(0.01, 0.05, n)),
        k2=tuple(rng.uniform(-0.1, -0.01, n)),
        k1=0.2,
    )
    opts = ModelOptions(bands="linear", noise=ModelOptions().noise.__class__(seed=3, band_spread=0.1, eta_spread=0.1))
    m = make_model("lattice", p, [], opts)
    from host_emulator.models.plant import spreads

    band, eta = spreads(p, opts, n)
    a, e, i = chain.chain_matrices(p, band_factors=band, eta_factors=eta)
    h = 1e-6
    fd = np.empty((2 * n, 2 * n))
    for k in range(2 * n):
        x = np.zeros(2 * n)
        x[k] = h
        fp, _ = m.forces(0.0, x)
        fm, _ = m.forces(0.0, -x)
        fd[:, k] = (fp - fm) / (2 * h)
    _, c = m.forces(0.0, np.zeros(2 * n))
    assert np.allclose(fd, a, rtol=1e-7, atol=1e-10)
    assert np.allclose(np.diag(e), c, rtol=1e-12)
    assert np.allclose(np.diag(i), [p.I_a] * n + [p.I_b] * n)


def test_a_heterogeneous_chain_places_its_walls():
    """Cells 1-8 stable on their own (k2 = +0.03: psi'' > 0, sigma 0) and 9-16 patterning (the source's law): the
    leading mode lives on the patterned half."""
    p = Params(sigma=(0.0,) * 8 + (0.072,) * 8, k2=(0.03,) * 8 + (-0.06,) * 8)
    res = chain.chain_modes(p, theory_of("lattice", p), count=3)
    top = res["modes"][0]
    assert top["growth_per_s"] > 0 and top["kind"] == "stationary"
    assert np.abs(top["alpha"][:6]).max() < 0.2 < np.abs(top["alpha"][8:]).max()
    assert all(w > 8 for w in top["walls"])
    summ = chain.chain_summary(p, theory_of("lattice", p))
    assert summ["regime"] == "stationary_pattern" and summ["fastest_growth_per_s"] == top["growth_per_s"]


def test_mode_walls_reads_sign_changes_above_the_threshold():
    assert chain.mode_walls(np.array([1.0, 0.5, -0.5, -1.0])) == [2.5]
    assert chain.mode_walls(np.array([1.0, 0.05, -0.02, 1.0])) == []  # small cells take no part
    assert chain.mode_walls(np.zeros(4)) == []
    w = chain.mode_walls(np.array([1.0, 0.75, -0.25, -1.0]))
    assert w == [pytest.approx(2.75)]
