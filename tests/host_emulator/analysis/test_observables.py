"""Observables on synthetic runs with a known spatial period, temporal period, growth rate and steadiness."""

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st

from host_emulator.analysis.observables import (
    REST_TOL_RAD,
    domain_walls,
    dominant_mode,
    growth_rate,
    observables,
    spatial_period,
    temporal_period,
)

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
    a, b = run(t, lambda tt: 0.5 * np.cos(2 * np.pi * X16 / 8 - 3 * tt))  # travelling wave
    assert observables(t, a, b)["steady"] is False
    a, b = run(t, lambda tt: np.full(16, 0.2 * tt))  # slow drift
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


# ---- the source's reading of a pattern ----------------------------------------------------------------------


@settings(max_examples=80, deadline=None)
@given(st.integers(2, 64), st.data())
def test_dominant_mode_of_a_free_end_mode_is_its_index(n, data):
    """cos(pi m (j - 1/2) / n) plus a smaller other mode: the transform picks m."""
    m = data.draw(st.integers(0, n - 1))
    other = data.draw(st.integers(0, n - 1))
    amp = data.draw(st.floats(0.05, 2.0))
    x = np.arange(n) + 0.5
    u = amp * np.cos(np.pi * m * x / n) + (0.4 * amp if other != m else 0.0) * np.cos(np.pi * other * x / n)
    assert dominant_mode(u) == m


@settings(max_examples=80, deadline=None)
@given(st.lists(st.sampled_from([-1, 1]), min_size=1, max_size=40), st.data())
def test_domain_walls_count_sign_changes_of_the_clear_cells_only(signs, data):
    """Blocks of clear +-0.6 rad cells separated by near-zero cells (inside a wall): walls = sign changes of
    the blocks, whatever sits near zero in between."""
    u = []
    for s in signs:
        u += [0.6 * s] * data.draw(st.integers(1, 4))
        u += [data.draw(st.floats(-0.09, 0.09))] * data.draw(st.integers(0, 2))
    want = sum(1 for a, b in zip(signs, signs[1:]) if a != b)
    assert domain_walls(u) == want


def test_pattern_wavelength_follows_the_sources_convention_and_rest_reports_none():
    t = np.linspace(0, 1, 50)
    n = 16
    x = np.arange(n) + 0.5
    for m, walls in ((2, 2), (3, 3), (4, 4)):
        prof = 0.6 * np.cos(np.pi * m * x / n)
        a = np.tile(prof, (t.size, 1))
        o = observables(t, a, 0 * a)
        assert o["domain_walls"] == walls and o["pattern_wavelength_cells"] == pytest.approx(30 / walls)
        assert o["dominant_mode"] == m and not o["at_rest"]
    quiet = np.full((t.size, n), 0.9 * REST_TOL_RAD) * np.sign(np.cos(np.pi * 2 * x / n))
    o = observables(t, quiet, 0 * quiet)
    assert o["at_rest"] and o["pattern_period_cells"] is None and o["domain_walls"] == 0
    assert o["dominant_mode"] is None and o["pattern_wavelength_cells"] is None
