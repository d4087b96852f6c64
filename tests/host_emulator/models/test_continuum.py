"""Continuum PDE model: linear growth vs dispersion, rest stays rest, pure-diffusion balance, clear errors."""

import math

import numpy as np
import pytest

from host_emulator.analysis.stability import growth_rates
from host_emulator.models.continuum import ContinuumError, simulate_continuum
from host_emulator.params import Params

N = 16


def mode_growth(p, m, t_end, eps=1e-3, ppc=8):
    """Start in the linear eigenvector of free-end mode m; return (measured rate, predicted rate)."""
    kappa = math.pi * m / N
    q = kappa**2
    a = np.array([[-p.k_ab - p.k2 - q * p.ka_eff, p.k_ab - p.sigma], [p.k_ab, -p.k_ab - q * p.kb_eff]])
    w, v = np.linalg.eig(a / np.array([p.eta_alpha, p.eta_beta])[:, None])
    i = int(np.argmax(w.real))
    assert abs(w[i].imag) < 1e-12
    vec = v[:, i].real / np.abs(v[:, i].real).max()

    def init(x):
        return eps * vec[0] * np.cos(kappa * x), eps * vec[1] * np.cos(kappa * x)

    t, al, be = simulate_continuum(
        p, N, t_end, [], dt_out_s=t_end / 50, points_per_cell=ppc, initial=init, rtol=1e-8, atol=1e-13
    )
    shape = np.cos(kappa * (np.arange(N) + 0.5))
    amp = al @ shape / (shape @ shape)  # projection on the mode
    assert np.abs(al).max() < 0.5  # stayed on the linear branch of psi'
    slope = np.polyfit(t, np.log(np.abs(amp)), 1)[0]
    pred = growth_rates(p, [kappa], discrete=False)[0, 0].real
    return slope, pred


@pytest.mark.parametrize("sigma,m", [(9 / 125, 5), (6 / 125, 3), (14 / 125, 6)])
def test_single_mode_rate_matches_dispersion(sigma, m):
    p = Params(sigma=sigma)
    pred = growth_rates(p, [math.pi * m / N], discrete=False)[0, 0].real
    t_end = min(5.0 / abs(pred), 1.0)  # ~5 e-folds, all within the linear branch
    got, pred = mode_growth(p, m, t_end, eps=1e-3 if pred > 0 else 0.3)
    assert got == pytest.approx(pred, rel=0.02)


def test_rest_stays_rest():
    t, a, b = simulate_continuum(Params(), N, 1.0, [])
    assert t[0] == 0 and t[-1] == pytest.approx(1.0) and a.shape == b.shape == (t.size, N)
    assert np.all(a == 0) and np.all(b == 0)


@pytest.mark.parametrize("t_end,dt", [(0.1037, 0.1037 / 50), (0.3, 0.1), (0.25, 0.1), (1.0, 1.0)])
def test_output_times_end_exactly_at_t_end(t_end, dt):
    t, a, _ = simulate_continuum(Params(), 4, t_end, [], dt_out_s=dt)
    assert t[0] == 0 and t[-1] == t_end and np.all(np.diff(t) > 0) and np.all(np.diff(t) <= dt * (1 + 1e-9))
    assert np.all(np.isfinite(a))


def test_pure_diffusion_conserves_impulse_and_flattens():
    """Reaction off: eta_a d/dt int alpha dx = int P dx (no-flux ends), so alpha -> T tau / (eta_a N)."""
    p = Params(sigma=0.0, k_ab=0.0, k1=0.0, k2=0.0)
    torque, dur = 2e-3, 0.05
    t, a, b = simulate_continuum(
        p,
        N,
        8.0,
        [dict(cell=3, chain="alpha", torque_Nm=torque, start_s=0.1, duration_s=dur)],
        dt_out_s=0.02,
        rtol=1e-9,
        atol=1e-12,
    )
    assert np.all(b == 0)
    want = torque * dur / (p.eta_alpha * N)
    assert a[-1] == pytest.approx(np.full(N, want), rel=1e-3)
    spread = np.ptp(a, axis=1)[t > 0.15 + 1e-9]  # after the pulse: variance only decays
    assert np.all(np.diff(spread) <= 1e-12)
    # before the pulse nothing moves, at its end the peak sits on cell 3
    assert np.all(a[t < 0.1 - 1e-9] == 0)
    assert int(np.argmax(a[np.searchsorted(t, 0.15)])) == 2


def test_beta_perturbation_and_symmetry():
    """CCW-CCW at cells 6 and 11 of 16 is mirror symmetric; the pattern is mirror symmetric too."""
    p = Params()
    pert = [dict(cell=c, chain="alpha", torque_Nm=0.01, start_s=0.0, duration_s=0.02) for c in (6, 11)]
    t, a, b = simulate_continuum(p, N, 0.5, pert, dt_out_s=0.05)
    assert np.allclose(a, a[:, ::-1], atol=1e-6)
    t, a, b = simulate_continuum(
        p, N, 0.1, [dict(cell=4, chain="beta", torque_Nm=1e-3, start_s=0.0, duration_s=0.01)], dt_out_s=0.01
    )
    assert np.abs(b[:, 3]).max() > np.abs(b[:, 10]).max() > 0


@pytest.mark.parametrize(
    "bad,match",
    [
        (dict(cell=0), "cell"),
        (dict(cell=17), "cell"),
        (dict(chain="gamma"), "chain"),
        (dict(duration_s=0.0), "duration_s"),
        (dict(torque_Nm=float("nan")), "torque_Nm"),
        (dict(extra=1), "unknown"),
    ],
)
def test_bad_perturbation_rejected(bad, match):
    good = dict(cell=8, chain="alpha", torque_Nm=0.01, start_s=0.0, duration_s=0.01)
    with pytest.raises(ValueError, match=match):
        simulate_continuum(Params(), N, 0.1, [{**good, **bad}])


def test_bad_arguments_rejected():
    with pytest.raises(ValueError, match="t_end_s"):
        simulate_continuum(Params(), N, 0.0, [])
    with pytest.raises(ValueError, match="cells"):
        simulate_continuum(Params(), 0, 1.0, [])
    with pytest.raises(ValueError, match="eta_alpha"):
        simulate_continuum(Params(eta_scale=0.0), N, 1.0, [])


def test_unbounded_growth_stops_with_a_named_cause():
    """No saturating branch (k1 = k2 < 0) and det J < 0: the uniform mode grows without bound."""
    p = Params(sigma=6 / 125, k1=-0.06, k2=-0.06)
    with pytest.raises(ContinuumError, match="diverged"):
        simulate_continuum(
            p, N, 5.0, [dict(cell=8, chain="alpha", torque_Nm=0.01, start_s=0.0, duration_s=0.01)], max_angle_rad=100.0
        )


@pytest.mark.parametrize("sigma,eta_scale", [(9 / 125, 1.0), (6 / 125, 1.0), (14 / 125, 10.0)])
def test_single_kick_outcome_follows_the_regime(sigma, eta_scale):
    """Scene 3/4 in the continuum: a pattern whose period lies in the unstable band, or a return to rest."""
    from host_emulator.analysis.observables import observables
    from host_emulator.analysis.stability import dispersion

    p = Params(sigma=sigma, eta_scale=eta_scale)
    d = dispersion(p, discrete=False)
    t, a, b = simulate_continuum(
        p,
        N,
        3.0 * eta_scale,
        [dict(cell=8, chain="alpha", torque_Nm=0.01, start_s=0.05, duration_s=0.05)],
        dt_out_s=0.01,
    )
    o = observables(t, a, b)
    assert o["steady"]
    if d["regime"] == "rest":
        assert o["pattern_period_cells"] is None and o["amplitude_rad"] < 1e-3
    else:
        [[lo, hi]] = d["unstable_set_cells"]
        assert lo < o["pattern_period_cells"] < (hi or 2 * N)
        # saturated on the outer branches of psi' (|alpha| beyond the breakpoint k1 alpha*/(k1 - k2))
        assert o["amplitude_rad"] > p.k1 * p.alpha_star / (p.k1 - p.k2)


def test_observed_growth_rate_of_a_single_mode_run():
    """observables' early-growth fit on a real run that grows from 1e-5 rad into saturation."""
    from host_emulator.analysis.observables import observables

    p = Params(sigma=9 / 125)
    m = 3  # lambda = 10.7 cells, inside the unstable band at the rig's stiffness
    kappa = math.pi * m / N
    q = kappa**2
    a = np.array([[-p.k_ab - p.k2 - q * p.ka_eff, p.k_ab - p.sigma], [p.k_ab, -p.k_ab - q * p.kb_eff]])
    w, v = np.linalg.eig(a / np.array([p.eta_alpha, p.eta_beta])[:, None])
    vec = v[:, int(np.argmax(w.real))].real
    vec /= np.abs(vec).max()

    def init(x):
        return 1e-5 * vec[0] * np.cos(kappa * x), 1e-5 * vec[1] * np.cos(kappa * x)

    t, al, be = simulate_continuum(p, N, 1.5, [], dt_out_s=0.005, points_per_cell=8, initial=init)
    o = observables(t, al, be)
    pred = growth_rates(p, [kappa], discrete=False)[0, 0].real
    assert o["growth_rate_per_s"] == pytest.approx(pred, rel=0.03)
    assert o["steady"] and o["pattern_period_cells"] == pytest.approx(2 * N / m, rel=0.05)
