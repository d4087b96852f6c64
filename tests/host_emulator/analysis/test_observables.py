"""Observables on synthetic runs with a known spatial period, temporal period, growth rate and steadiness."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host_emulator.analysis.observables import observables, spatial_period, temporal_period, growth_rate

X16 = np.arange(16) + 0.5


@settings(max_examples=60, deadline=None)
@given(st.floats(2.5, 12.0), st.floats(0, 2 * math.pi), st.floats(0.2, 1.0), st.integers(0, 2**32 - 1))
def test_spatial_period_of_noisy_sine(lam, phase, amp, seed):
    rng = np.random.default_rng(seed)
    u = amp * np.cos(2 * np.pi * X16 / lam + phase) + 0.01 * rng.standard_normal(16) + 0.3
    assert spatial_period(u) == pytest.approx(lam, rel=0.03)


@pytest.mark.parametrize("lam", [4.0, 6.4, 8.0])
def test_spatial_period_of_saturated_pattern(lam):
    """Bistable cells saturate near +-alpha*: a square-ish wave keeps its period."""
    u = 0.66 * np.tanh(3 * np.cos(2 * np.pi * X16 / lam + 0.3))
    assert spatial_period(u) == pytest.approx(lam, rel=0.05)


def test_flat_profile_has_no_pattern():
    assert spatial_period(np.full(16, 0.2)) is None
    assert spatial_period(0.001 * np.cos(X16)) is None


def run(t, f_alpha, n=16):
    a = np.array([f_alpha(tt) for tt in t])
    return a, 0.5 * a


def test_steady_pattern():
    t = np.linspace(0, 2, 401)
    pattern = 0.6 * np.cos(2 * np.pi * X16 / 8)
    a, b = run(t, lambda tt: pattern * (1 - np.exp(-tt / 0.1)))
    o = observables(t, a, b)
    assert o["steady"] is True
    assert o["pattern_period_cells"] == pytest.approx(8, rel=0.01)
    assert o["oscillation_period_s"] is None
    assert o["amplitude_rad"] == pytest.approx(0.6 * np.abs(np.cos(2 * np.pi * X16 / 8)).max(), rel=1e-3)
    assert o["final_alpha_rad"] == pytest.approx(list(a[-1]))
    assert o["final_beta_rad"] == pytest.approx(list(b[-1]))


def test_moving_run_is_not_steady():
    t = np.linspace(0, 2, 401)
    a, b = run(t, lambda tt: 0.5 * np.cos(2 * np.pi * X16 / 8 - 3 * tt))      # travelling wave
    assert observables(t, a, b)["steady"] is False
    a, b = run(t, lambda tt: np.full(16, 0.2 * tt))                              # slow drift
    assert observables(t, a, b)["steady"] is False


def test_quantisation_jitter_is_steady_and_no_oscillation():
    rng = np.random.default_rng(1)
    step = 2 * np.pi / 400
    t = np.linspace(0, 2, 801)
    final = np.round(0.6 * np.cos(2 * np.pi * X16 / 6.4) / step) * step
    a = final + step * rng.integers(-1, 1, size=(t.size, 16)) * (t[:, None] > 0.5)
    a[t < 0.5] = 0.0
    o = observables(t, a, a)
    assert o["steady"] is True
    assert o["oscillation_period_s"] is None


@settings(max_examples=30, deadline=None)
@given(st.floats(0.05, 0.5), st.floats(0.3, 3.0), st.floats(0.05, 1.0))
def test_decaying_oscillation_period(period, tau_periods, amp):
    """alpha = A exp(-t/tau) cos(2 pi t / T): zero crossings are exactly T/2 apart."""
    tau = tau_periods * period
    t = np.linspace(0, 8 * period, 2001)
    shape = np.cos(np.pi * X16 / 16)
    a = amp * np.exp(-t / tau)[:, None] * np.cos(2 * np.pi * t / period)[:, None] * shape
    got = temporal_period(t, a)
    # enough cycles above the one-count band?  then the period must be right
    n_visible = 2 * tau / period * math.log(amp / (2 * np.pi / 400)) if amp > 2 * np.pi / 400 else 0
    if n_visible >= 4:
        assert got == pytest.approx(period, rel=0.01)
    if got is not None:
        assert got == pytest.approx(period, rel=0.01)


def test_sustained_oscillation_with_noise():
    rng = np.random.default_rng(2)
    t = np.linspace(0, 3, 3001)
    a = 0.3 * np.sin(2 * np.pi * t / 0.41)[:, None] * np.ones(16) + 0.003 * rng.standard_normal((t.size, 16))
    o = observables(t, a, a)
    assert o["oscillation_period_s"] == pytest.approx(0.41, rel=0.01)
    assert o["steady"] is False


@settings(max_examples=30, deadline=None)
@given(st.floats(5.0, 60.0), st.floats(1e-5, 1e-3))
def test_growth_rate_of_saturating_exponential(g, a0):
    """alpha = sat * tanh(a0 e^{g t} / sat) * mode: early growth e^{g t} until saturation."""
    t_sat = math.log(0.6 / a0) / g
    t = np.linspace(0, 1.5 * t_sat, 600)
    mode = np.cos(2 * np.pi * X16 / 6.4)
    a = 0.6 * np.tanh(a0 * np.exp(g * t) / 0.6)[:, None] * mode
    assert growth_rate(t, a) == pytest.approx(g, rel=0.03)


def test_no_growth_gives_none():
    t = np.linspace(0, 1, 200)
    a = 0.1 * np.exp(-5 * t)[:, None] * np.ones(16)
    assert growth_rate(t, a) is None
    assert growth_rate(t, np.zeros((200, 16))) is None


def test_bad_input():
    t = np.linspace(0, 1, 10)
    a = np.zeros((10, 16))
    with pytest.raises(ValueError, match="shape"):
        observables(t, a, np.zeros((10, 15)))
    bad = a.copy()
    bad[3, 2] = np.nan
    with pytest.raises(ValueError, match="non-finite"):
        observables(t, bad, a)
    with pytest.raises(ValueError, match="increasing"):
        observables(t[::-1], a, a)
    with pytest.raises(ValueError, match="tol_rad"):
        observables(t, a, a, tol_rad=0)
