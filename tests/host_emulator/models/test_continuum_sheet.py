"""Continuum PDE on a square sheet: exponential-integrator coefficients, agreement of the two steppers and with the
1-D model, numbering, conservation, the isotropic 2-D dispersion relation, clear refusals."""

import math

import numpy as np
import pytest
import scipy.linalg as sl

from host_emulator.analysis.stability import growth_rates
from host_emulator.models.continuum import simulate_continuum
from host_emulator.models.continuum_sheet import _COMBOS, matrix_phi
from host_emulator.params import Params


def sheet(rows, cols, boundary="open", **kw):
    return Params(cells=rows * cols, shape=(rows, cols), lattice="square", boundary=boundary, **kw)


def phi_reference(a, k):
    """phi_0..phi_k(A) of a 2 x 2 matrix from one exponential of the augmented matrix [[A, I, 0..], [0, 0, I..]]."""
    n = 2 * (k + 1)
    big = np.zeros((n, n))
    big[:2, :2] = a
    for j in range(k):
        big[2 * j : 2 * j + 2, 2 * j + 2 : 2 * j + 4] = np.eye(2)
    e = sl.expm(big)
    return [e[:2, :2]] + [e[:2, 2 * j : 2 * j + 2] for j in range(1, k + 1)]


@pytest.mark.parametrize(
    "a",
    [
        [[0.3, -1.2], [4.0, -2.0]],  # complex pair
        [[-5.0, 0.4], [1.0, -80.0]],  # stiff, real
        [[-2.0, 1.0], [0.0, -2.0]],  # a double eigenvalue (a Jordan block)
        [[-2.0, 1.0], [1e-9, -2.0 + 1e-7]],  # nearly so: the divided differences' Taylor branch
        [[1e-4, 2e-4], [-3e-4, 5e-5]],  # near zero: the phi series
        [[-700.0, 3.0], [-2.0, -0.5]],
    ],
)
def test_matrix_phi_matches_the_augmented_exponential(a):
    a = np.array(a)
    got = matrix_phi(a, list(_COMBOS))
    ph = phi_reference(a, 3)
    for name, combo in _COMBOS.items():
        want = sum(c * ph[k] for k, c in combo.items())
        assert np.allclose(got[name], want, rtol=1e-10, atol=1e-13), name


def push(cell, chain="alpha", torque=5e-3, start=0.02, dur=0.03):
    return dict(cell=cell, chain=chain, torque_Nm=torque, start_s=start, duration_s=dur)


@pytest.mark.parametrize("boundary", ["open", "periodic"])
def test_etdrk4_and_bdf_agree_on_a_pushed_sheet(boundary):
    """The two steppers (spectral exponential integrator; sparse-Jacobian BDF) solve the same semi-discrete PDE."""
    p = sheet(4, 5, boundary, sigma=9 / 125)
    perts = [push(7), push(14, "beta", 1e-3, 0.0, 0.05)]
    kw = dict(dt_out_s=0.025, points_per_cell=2, rtol=1e-7, atol=1e-10)
    t, a1, b1 = simulate_continuum(p, 20, 0.15, perts, method="etdrk4", **kw)
    _, a2, b2 = simulate_continuum(p, 20, 0.15, perts, method="BDF", **kw)
    assert a1.shape == (t.size, 20) and np.abs(a1).max() > 0.05
    # both at rtol 1e-7: each within ~1e-6 rad of the exact semi-discrete solution
    assert np.abs(a1 - a2).max() < 1e-5 and np.abs(b1 - b2).max() < 1e-5


@pytest.mark.parametrize("method", ["etdrk4", "BDF"])
def test_a_sheet_uniform_down_its_columns_is_the_chain(method):
    """Push every cell of column 3 and give the cells per-column laws: the sheet is the 1-D model along a row."""
    rows, cols = 3, 6
    sig = (0.06, 0.072, 0.08, 0.072, 0.05, 0.07)
    ps = sheet(rows, cols, sigma=sig * rows)
    pc = Params(cells=cols, sigma=sig)
    kw = dict(dt_out_s=0.05, points_per_cell=2, rtol=1e-7, atol=1e-10)
    t, a1, b1 = simulate_continuum(ps, rows * cols, 0.2, [push(3 + cols * r) for r in range(rows)], method=method, **kw)
    _, a2, b2 = simulate_continuum(pc, cols, 0.2, [push(3)], **kw)
    assert np.abs(a2).max() > 0.05
    for r in range(rows):  # each at rtol 1e-7: within ~1e-6 rad of the exact semi-discrete solution
        assert np.abs(a1[:, r * cols : (r + 1) * cols] - a2).max() < 1e-5
        assert np.abs(b1[:, r * cols : (r + 1) * cols] - b2).max() < 1e-5


@pytest.mark.parametrize("boundary", ["open", "periodic"])
def test_pure_diffusion_on_a_sheet_conserves_the_impulse(boundary):
    """Reaction off: the pushed impulse T tau spreads over the whole sheet, alpha -> T tau / (eta_a n)."""
    p = sheet(4, 6, boundary, sigma=0.0, k_ab=0.0, k1=0.0, k2=0.0)
    torque, dur = 2e-3, 0.05
    t, a, b = simulate_continuum(p, 24, 6.0, [push(9, torque=torque, start=0.1, dur=dur)], dt_out_s=0.5, rtol=1e-8)
    assert np.all(b == 0)
    assert a[-1] == pytest.approx(np.full(24, torque * dur / (p.eta_alpha * 24)), rel=1e-3)


def test_cell_numbers_run_row_by_row():
    """A push on cell (row 2, col 5) of a 3 x 7 sheet peaks there, and the mirror pushes give mirrored fields."""
    p = sheet(3, 7, sigma=0.11)
    cell = 1 * 7 + 5  # (row 2, col 5)
    t, a, _ = simulate_continuum(p, 21, 0.1, [push(cell, start=0.0, dur=0.05)], dt_out_s=0.05)
    grid = a[1].reshape(3, 7)  # at the end of the push (later the field oscillates and the peak moves)
    assert np.unravel_index(np.argmax(grid), grid.shape) == (1, 4)
    _, a2, _ = simulate_continuum(p, 21, 0.1, [push(1 * 7 + 3, start=0.0, dur=0.05)], dt_out_s=0.05)
    assert np.allclose(a2.reshape(-1, 3, 7), a.reshape(-1, 3, 7)[:, :, ::-1], atol=1e-7)


@pytest.mark.parametrize("mode,ppc", [((1, 1), 8), ((2, 1), 8), ((0, 1), 8)])
def test_a_2d_mode_grows_at_the_isotropic_rate(mode, ppc):
    """cos(k . x) with a 2-D wavevector on a periodic sheet grows at the 1-D continuum rate at |k| (symbol |k|^2)."""
    n = 12
    p = sheet(n, n, "periodic", sigma=9 / 125)
    k = 2 * math.pi * np.array(mode) / n  # (k_col, k_row) rad/cell
    kk = float(np.hypot(*k))
    q = kk * kk
    mat = np.array([[-p.k_ab - p.k2 - q * p.ka_eff, p.k_ab - p.sigma], [p.k_ab, -p.k_ab - q * p.kb_eff]])
    w, v = np.linalg.eig(mat / np.array([p.eta_alpha, p.eta_beta])[:, None])
    vec = v[:, int(np.argmax(w.real))].real
    vec /= np.abs(vec).max()
    pred = growth_rates(p, [kk], discrete=False)[0, 0].real
    eps = 1e-3

    def init(x, y):
        c = np.cos(k[0] * x + k[1] * y)
        return eps * vec[0] * c, eps * vec[1] * c

    t_end = min(4.0 / abs(pred), 0.5)
    t, a, _ = simulate_continuum(p, n * n, t_end, [], dt_out_s=t_end / 20, points_per_cell=ppc, initial=init, rtol=1e-8)
    rc = np.indices((n, n)).reshape(2, -1) + 0.5  # (row, col) centres
    shape = np.cos(k[0] * rc[1] + k[1] * rc[0])
    amp = a @ shape / (shape @ shape)
    assert np.abs(a).max() < 0.5  # linear branch
    slope = np.polyfit(t, np.log(np.abs(amp)), 1)[0]
    assert slope == pytest.approx(pred, rel=0.02)


def test_ring_is_periodic_and_translation_invariant():
    """A ring's continuum wraps: pushing cell 2 or cell 6 of 8 gives the same field rolled by 4 cells."""
    p = Params(cells=8, boundary="periodic", sigma=9 / 125)
    _, a1, _ = simulate_continuum(p, 8, 0.3, [push(2)], dt_out_s=0.1)
    _, a2, _ = simulate_continuum(p, 8, 0.3, [push(6)], dt_out_s=0.1)
    assert np.abs(a1).max() > 0.01
    assert np.allclose(np.roll(a1, 4, axis=1), a2, atol=1e-7)
    assert np.allclose(a1[-1], np.roll(a1[-1][::-1], 3), atol=1e-7)  # mirror about cell 2 (wraps through cell 8)


def test_refusals_name_their_reason():
    hexp = Params(cells=9, shape=(3, 3), lattice="hex")
    with pytest.raises(ValueError, match="isotropic.*square"):
        simulate_continuum(hexp, 9, 0.1, [])
    p = sheet(3, 3)
    with pytest.raises(ValueError, match="cells=8"):
        simulate_continuum(p, 8, 0.1, [])
    with pytest.raises(ValueError, match="spreads"):
        simulate_continuum(p, 9, 0.1, [], spread=(np.ones((2, 9)), np.ones((2, 9))))
    with pytest.raises(ValueError, match="method"):
        simulate_continuum(p, 9, 0.1, [], method="RK45x")
    with pytest.raises(ValueError, match="cell"):
        simulate_continuum(p, 9, 0.1, [push(10)])


def test_adapter_runs_a_sheet():
    from host_emulator.models import make_model
    from host_emulator.models.options import ModelOptions, Perturbation

    p = sheet(3, 4, sigma=9 / 125)
    model = make_model("continuum", p, [Perturbation(6, "alpha", 5e-3, 0.0, 0.05)], ModelOptions(points_per_cell=2))
    s = model.solver()
    t, a, b = s.run_all(0.2)
    assert a.shape == b.shape == (t.size, 12) and np.abs(a).max() > 0
    assert "ETDRK4" in s.info()["stepper"]
