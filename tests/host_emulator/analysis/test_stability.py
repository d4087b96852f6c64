"""Linear stability analysis checked against closed forms, polynomial roots and the assembled lattice matrix."""

import math

import numpy as np
import pytest
from hypothesis import assume, example, given, settings
from hypothesis import strategies as st
from scipy.optimize import linear_sum_assignment

from host_emulator.analysis import stability as stab
from host_emulator.params import Params

# the source's three gains and their regimes in the source's own (overdamped, no-inertia) theory
SIGMAS = {"stationary_pattern": 9 / 125, "broadband_pattern": 6 / 125, "rest": 14 / 125}


def omega_closed_form(p, kappa, discrete):
    """docs/physics.md#linear-stability as written: Omega = (tr J_k +- sqrt(tr^2 - 4 det)) / 2 / eta_a, J_k = J - q
    diag(k_a, k_b/gamma)."""
    g = p.gamma
    j = np.array([[-p.k_ab - p.k2, p.k_ab - p.sigma], [p.k_ab / g, -p.k_ab / g]])
    q = 2 * (1 - np.cos(kappa)) if discrete else kappa**2
    a = j[0, 0] - q * p.ka_eff
    d = j[1, 1] - q * p.kb_eff / g
    tr, det = a + d, a * d - j[0, 1] * j[1, 0]
    root = np.sqrt((tr * tr - 4 * det).astype(complex))
    return np.stack([(tr + root) / 2, (tr - root) / 2], axis=1) / p.eta_alpha


def quartic_roots(p, kappa, discrete):
    """Roots of det(I s^2 + E s - A(q)) = 0 built as a polynomial (independent of the companion matrix)."""
    q = 2 * (1 - math.cos(kappa)) if discrete else kappa**2
    a00 = -p.k_ab - p.k2 - q * p.ka_eff
    a01 = p.k_ab - p.sigma
    a10 = p.k_ab
    a11 = -p.k_ab - q * p.kb_eff
    pa = np.array([p.I_a, p.eta_alpha, -a00])
    pb = np.array([p.I_b, p.eta_beta, -a11])
    poly = np.polymul(pa, pb)
    poly[-1] -= a01 * a10
    return np.roots(poly)


def sort_desc(z):
    z = np.asarray(z)
    return z[np.lexsort((-z.imag, -z.real))]


params_st = st.builds(
    lambda s, kab, k2, g, es: Params(sigma=s, k_ab=kab, k2=k2, gamma=g, eta_scale=es),
    st.floats(0.0, 0.2),
    st.floats(0.005, 0.05),
    st.floats(-0.1, 0.02),
    st.floats(0.05, 1.0),
    st.floats(0.5, 20.0),
)


@settings(max_examples=60, deadline=None)
@given(params_st, st.floats(0.0, 6.0), st.booleans())
def test_growth_rates_match_spec_closed_form(p, kappa, discrete):
    got = stab.growth_rates(p, [kappa], discrete=discrete)[0]
    want = sort_desc(omega_closed_form(p, np.array([kappa]), discrete)[0])
    scale = max(1.0, np.abs(want).max())
    assert np.allclose(got, want, rtol=1e-9, atol=1e-7 * scale)
    assert got[0].real >= got[1].real


@settings(max_examples=40, deadline=None)
@given(params_st, st.floats(0.0, 3.0), st.booleans())
def test_inertial_growth_rates_match_quartic_roots(p, kappa, discrete):
    got = stab.growth_rates(p, [kappa], discrete=discrete, inertia=True)[0]
    want = quartic_roots(p, kappa, discrete)
    scale = np.abs(want).max()
    # compare as multisets: each computed root has a polynomial root nearby
    for z in got:
        assert np.min(np.abs(want - z)) < 1e-6 * scale
    assert np.all(np.diff(got.real) <= 1e-9 * scale)


def test_inertia_negligible_when_slow():
    """Tiny inertia: the two slow roots of the quartic approach the overdamped rates."""
    p = Params(I_a=1e-15, I_b=1e-15)
    k = np.linspace(0.1, 3, 7)
    slow = stab.growth_rates(p, k, inertia=True)[:, :2]
    over = stab.growth_rates(p, k)
    assert np.allclose(slow, over, rtol=1e-4, atol=1e-3)


def assembled_matrix(p, n, periodic, inertia):
    """Linearised equations of motion of an n-cell chain, state (alpha_1..n, beta_1..n[, velocities])."""
    lap = np.zeros((n, n))
    for j in range(n):
        for nb in (j - 1, j + 1):
            if periodic or 0 <= nb < n:
                lap[j, nb % n] += 1.0
                lap[j, j] -= 1.0  # a missing neighbour contributes no torque (free end)
    jr = stab.reaction_jacobian(p)
    eye = np.eye(n)
    a = np.block([[p.ka_eff * lap + jr[0, 0] * eye, jr[0, 1] * eye], [jr[1, 0] * eye, p.kb_eff * lap + jr[1, 1] * eye]])
    eta = np.concatenate([np.full(n, p.eta_alpha), np.full(n, p.eta_beta)])
    if not inertia:
        return a / eta[:, None]
    inert = np.concatenate([np.full(n, p.I_a), np.full(n, p.I_b)])
    z = np.zeros((2 * n, 2 * n))
    return np.block([[z, np.eye(2 * n)], [a / inert[:, None], -np.diag(eta / inert)]])


@pytest.mark.parametrize("sigma", list(SIGMAS.values()))
@pytest.mark.parametrize("periodic", [False, True])
@pytest.mark.parametrize("inertia", [False, True])
def test_discrete_dispersion_matches_assembled_lattice(sigma, periodic, inertia):
    n = 16
    p = Params(sigma=sigma)
    ev = np.linalg.eigvals(assembled_matrix(p, n, periodic, inertia))
    km = (2 * np.pi * np.arange(n) / n) if periodic else (np.pi * np.arange(n) / n)
    pred = stab.growth_rates(p, km, discrete=True, inertia=inertia).ravel()
    scale = np.abs(ev).max()
    assert len(pred) == len(ev)
    # multiset match (degenerate +-kappa pairs of the periodic chain make sorting ambiguous)
    rows, cols = linear_sum_assignment(np.abs(ev[:, None] - pred[None, :]))
    assert np.abs(ev[rows] - pred[cols]).max() < 1e-8 * scale
    if not periodic:
        d = stab.dispersion(p, inertia=inertia, n_cells=n)
        top = max(m["growth_per_s"] for m in d["lattice_modes"])
        assert top == pytest.approx(ev.real.max(), rel=1e-9, abs=1e-9 * scale)


def band_closed_form(p, discrete):
    """Wavelength band (cells) where det A(q) < 0, from the quadratic k_a k_b q^2 - b q + det Jr = 0."""
    jr = stab.reaction_jacobian(p)
    c2, c1, c0 = p.ka_eff * p.kb_eff, -(jr[0, 0] * p.kb_eff + jr[1, 1] * p.ka_eff), np.linalg.det(jr)
    qs = np.sort(np.roots([c2, c1, c0]).real)

    def lam(q):
        if q <= 0:
            return None
        if discrete:
            return None if q >= 4 else 2 * np.pi / np.arccos(1 - q / 2)
        return 2 * np.pi / np.sqrt(q)

    lo = 2.0 if discrete and qs[1] >= 4 else lam(qs[1])
    return [lo, lam(qs[0])]


@pytest.mark.parametrize("discrete", [True, False])
@pytest.mark.parametrize("regime", list(SIGMAS))
def test_three_sigmas_classify_as_the_source(regime, discrete):
    """Without inertia (the source's theory): 9/125 a finite band, 6/125 a band reaching the longest waves, 14/125
    nothing grows; the band edges agree with the closed form det A(q) = 0."""
    p = Params(sigma=SIGMAS[regime])
    d = stab.dispersion(p, discrete=discrete, n_cells=16)
    assert d["regime"] == regime
    if regime == "rest":
        assert d["unstable_set_cells"] == [] and d["fastest_growth_per_s"] < 0
    else:
        want = band_closed_form(p, discrete)
        [got] = d["unstable_set_cells"]
        assert [iv["kind"] for iv in d["unstable_intervals"]] == ["stationary"]
        assert got[0] == pytest.approx(want[0], rel=1e-7)
        if regime == "broadband_pattern":
            assert got[1] is None and d["uniform_mode_growth_per_s"] > 0
        else:
            assert got[1] == pytest.approx(want[1], rel=1e-7)
        assert got[0] < d["fastest_lambda_cells"] < (got[1] or np.inf)


@pytest.mark.parametrize("discrete", [True, False])
@pytest.mark.parametrize("regime", list(SIGMAS))
def test_regimes_with_inertia_and_tenfold_eta(regime, discrete):
    """Scene 4's setting (eta x10): inertia is a small correction, the classification is kept."""
    p = Params(sigma=SIGMAS[regime], eta_scale=10.0)
    assert stab.dispersion(p, discrete=discrete, inertia=True)["regime"] == regime


def test_inertia_at_nominal_eta_destabilises_the_stable_sigma_by_an_oscillation():
    """Finding: at 14/125 with eta_b = 0.1 eta_a, inertia makes the long waves oscillate with growing amplitude."""
    p = Params(sigma=14 / 125)
    d = stab.dispersion(p, inertia=True)
    k0 = stab.growth_rates(p, [0.0], inertia=True)[0, 0]
    assert d["regime"] == "uniform_oscillation"
    assert k0.real > 0 and abs(k0.imag) > 0
    assert d["oscillation_period_s"] == pytest.approx(2 * np.pi / abs(k0.imag), rel=1e-9)
    [iv] = d["unstable_intervals"]
    assert iv["kind"] == "oscillatory" and iv["lambda_cells"][1] is None and iv["fastest_lambda_cells"] is None


def test_twelve_over_125_with_inertia_has_two_unstable_intervals():
    """The issue's case: dispersion --sigma 12/125 --inertia --band-scale 0.5. A stationary (Turing) band and,
    apart from it, the oscillatory long waves; never reported as one envelope [4.51, inf)."""
    d = stab.dispersion(Params(sigma=12 / 125, band_scale=0.5), inertia=True)
    assert d["regime"] == "pattern_and_oscillation"
    (a_lo, a_hi), (b_lo, b_hi) = d["unstable_set_cells"]
    assert (round(a_lo, 2), round(a_hi, 2), round(b_lo, 2), b_hi) == (4.51, 7.54, 19.27, None)
    kinds = [iv["kind"] for iv in d["unstable_intervals"]]
    assert kinds == ["stationary", "oscillatory"]
    # between the pieces every mode decays; inside each the leading mode has the interval's kind
    for lam, grows, osc in ((6.0, True, False), (12.0, False, None), (40.0, True, True)):
        s = stab.growth_rates(Params(sigma=12 / 125, band_scale=0.5), [2 * np.pi / lam], inertia=True)[0, 0]
        assert (s.real > 0) == grows
        if grows:
            assert (abs(s.imag) > 1e-6) == osc


def test_hil_theory_adds_the_motors_back_emf_damping():
    """The hil model's theory: the uncompensated motors (Kt/S_L on every cylinder) keep 14/125 at rest, as the
    shipped hil scene does; with the firmware's 15/16 compensation the uniform oscillation returns."""
    p = Params(sigma=14 / 125)
    t = stab.theory_of("hil", p)
    assert t.motor_damping == pytest.approx(p.kt / p.speed_const)
    assert stab.dispersion(p, theory=t)["regime"] == "rest"
    tc = stab.theory_of("hil", p.with_overrides(bemf_comp=True))
    assert tc.motor_damping == pytest.approx(p.kt / p.speed_const / 16)
    assert stab.dispersion(p, theory=tc)["regime"] == "uniform_oscillation"
    assert stab.theory_of("continuum", p) == stab.Theory("continuum", False, False, 0.0)
    assert stab.theory_of("lattice", p, inertia=False).inertia is False


def test_bemf_fraction_is_the_firmwares():
    """The theory's compensated fraction is the library's MC_BEMF_FRAC_NUM / MC_BEMF_FRAC_DEN."""
    import re
    from pathlib import Path

    h = (Path(__file__).resolve().parents[3] / "lib/metacell/src/drivers/mc_drive.h").read_text()
    num = int(re.search(r"#define MC_BEMF_FRAC_NUM (\d+)u", h).group(1))
    den = int(re.search(r"#define MC_BEMF_FRAC_DEN (\d+)u", h).group(1))
    assert stab.BEMF_COMP_FRACTION == num / den


def chain_regime(p, n, inertia, damping):
    """Independent reference: the regime read off the eigenvalues of the full (second-order with inertia) linear
    system of a free-end chain of n cells, assembled cell by cell (assembled_matrix), with scipy.linalg.eig.

    Every growing eigenvalue is stationary (real) or oscillatory (complex); its eigenvector's alpha (or beta)
    part is one free-end mode cos(pi m (j - 1/2) / n), and m = 0 is the uniform mode."""
    from scipy.linalg import eig

    p2 = p.with_overrides(
        eta_a=(p.eta_alpha + damping) / p.eta_scale, gamma=(p.eta_beta + damping) / (p.eta_alpha + damping)
    )
    w, v = eig(assembled_matrix(p2, n, False, inertia))
    j = np.arange(n) + 0.5
    basis = np.cos(np.pi * np.outer(np.arange(n), j) / n)
    stat, osc = set(), set()
    for k in np.nonzero(w.real > 0)[0]:
        x = v[:n, k] if np.abs(v[:n, k]).max() > np.abs(v[n : 2 * n, k]).max() else v[n : 2 * n, k]
        m = int(np.argmax(np.abs(basis @ x)))
        (osc if abs(w[k].imag) > 1e-6 * abs(w[k]) else stat).add(m)
    if stat and osc:
        return "pattern_and_oscillation", w
    if osc:
        return "uniform_oscillation" if 0 in osc else "oscillation_without_uniform_mode", w
    if stat:
        return ("broadband_pattern" if 0 in stat else "stationary_pattern"), w
    return "rest", w


@settings(max_examples=50, deadline=None)
@given(
    st.floats(0.03, 0.16),
    st.sampled_from([0.5, 1.0, 2.0]),
    st.floats(0.3, 4.0),
    st.floats(0.05, 0.5),
    st.booleans(),
    st.sampled_from([0.0, 1.5e-4]),
)
@example(12 / 125, 0.5, 1.0, 0.1, True, 0.0)  # pattern_and_oscillation
@example(14 / 125, 1.0, 1.0, 0.1, True, 0.0)  # uniform_oscillation
@example(14 / 125, 1.0, 1.0, 0.1, True, 1.5e-4)  # the hil model: rest
@example(6 / 125, 1.0, 1.0, 0.1, False, 0.0)  # broadband_pattern
def test_regime_matches_the_eigenvalues_of_the_full_lattice(sigma, band_scale, eta_scale, gamma, inertia, damping):
    """The classifier (2x2 / 4x4 symbols on a kappa grid, brentq edges) against scipy's eigenvalues of the
    assembled 4n x 4n second-order system of a 96-cell free-end chain. Cases the chain's finite set of modes
    cannot resolve (a different answer at 64 cells: a band narrower than the mode spacing) are skipped."""
    p = Params(sigma=sigma, band_scale=band_scale, eta_scale=eta_scale, gamma=gamma)
    want, w = chain_regime(p, 96, inertia, damping)
    # a bifurcation point has no regime: sigma = -k2 (the uniform mode's determinant k_ab (k2 + sigma) is 0) or, without
    # inertia, gamma = k_ab / -(k_ab + k2) = 0.5 (its trace is 0: a Hopf point), both of them values the strategies
    # reach; there a mode's growth is 0 to rounding (|Re| ~ 1e-16 of the spectrum, against >= 7e-5 elsewhere) and
    # which side the two computations round to is chance
    assume(np.abs(w.real).min() > 1e-9 * np.abs(w).max())
    assume(chain_regime(p, 64, inertia, damping)[0] == want)
    got = stab.dispersion(p, inertia=inertia, motor_damping=damping, n_kappa=1000)["regime"]
    assert got == want


@settings(max_examples=60, deadline=None)
@given(st.floats(0.0, 0.2), st.floats(0.3, 20.0), st.floats(0.05, 1.0), st.floats(0.0, 3e-4), st.booleans())
def test_oscillatory_growth_always_includes_the_uniform_mode(sigma, eta_scale, gamma, damping, inertia):
    """What justifies the name uniform_oscillation: whenever an oscillatory interval grows, the uniform mode
    (kappa = 0) is unstable too (diffusion only damps: the bands add stiffness, never energy)."""
    p = Params(sigma=sigma, eta_scale=eta_scale, gamma=gamma)
    d = stab.dispersion(p, inertia=inertia, motor_damping=damping, n_kappa=400)
    if any(iv["kind"] == "oscillatory" for iv in d["unstable_intervals"]):
        assert d["uniform_mode_growth_per_s"] > 0
        assert d["unstable_set_cells"][-1][1] is None


def test_fastest_mode_is_the_grid_maximum():
    for sigma in (9 / 125, 6 / 125):
        for discrete in (True, False):
            p = Params(sigma=sigma)
            d = stab.dispersion(p, discrete=discrete, n_kappa=200)
            k = np.linspace(1e-4, np.pi, 200001)
            re = stab.growth_rates(p, k, discrete=discrete)[:, 0].real
            assert d["fastest_growth_per_s"] == pytest.approx(re.max(), rel=1e-8)
            assert d["fastest_lambda_cells"] == pytest.approx(2 * np.pi / k[np.argmax(re)], rel=1e-3)


def test_uniform_mode_period_closed_form():
    p = Params(sigma=14 / 125, eta_scale=10.0)
    j = stab.jacobian(p)
    tr, det = np.trace(j), np.linalg.det(j)
    assert 4 * det > tr * tr
    d = stab.dispersion(p)
    assert d["uniform_mode_period_s"] == pytest.approx(4 * np.pi * p.eta_alpha / np.sqrt(4 * det - tr * tr), rel=1e-9)
    assert d["oscillation_period_s"] is None  # the least stable mode (lambda ~ 5 cells) is real


@settings(max_examples=60, deadline=None)
@given(st.floats(0.0, 0.2), st.floats(0.005, 0.05), st.floats(-0.1, 0.0), st.floats(0.05, 1.0))
def test_turing_conditions_vs_sign_of_max_growth(sigma, kab, k2, gamma):
    p = Params(sigma=sigma, k_ab=kab, k2=k2, gamma=gamma)
    tc = stab.turing_conditions(p)
    # stay away from the thresholds, where the sign of a tiny max growth is a rounding question
    assume(abs(tc["trace_negative"]["value"]) > 1e-4 and abs(tc["det_positive"]["value"]) > 1e-6)
    assert tc["trace_negative"]["holds"] == (np.trace(stab.jacobian(p)) < 0)
    assert tc["det_positive"]["holds"] == (np.linalg.det(stab.jacobian(p)) > 0)
    if tc["diffusion_driven"]["value"] is not None:
        assume(abs(tc["diffusion_driven"]["value"]) > 1e-4)
    d = stab.dispersion(p, discrete=False, n_kappa=400)
    if tc["trace_negative"]["holds"] and tc["det_positive"]["holds"]:
        # uniform state stable; something grows iff diffusion destabilises (condition 3)
        assert (d["regime"] != "rest") == tc["diffusion_driven"]["holds"]
        assert d["regime"] in ("rest", "stationary_pattern")
    else:
        assert d["uniform_mode_growth_per_s"] > 0
        assert d["regime"] in ("broadband_pattern", "uniform_oscillation", "pattern_and_oscillation")


def test_bad_input_is_rejected():
    with pytest.raises(ValueError, match="eta_alpha"):
        stab.dispersion(Params(eta_a=-1.0))
    with pytest.raises(ValueError, match="I_a"):
        stab.growth_rates(Params(I_a=0.0), [1.0], inertia=True)
    with pytest.raises(ValueError, match="kappa"):
        stab.growth_rates(Params(), [np.nan])
    with pytest.raises(ValueError, match="n_cells"):
        stab.dispersion(Params(), n_cells=0)


def test_dispersion_is_json_ready():
    import json

    for inertia in (False, True):
        d = stab.dispersion(Params(sigma=6 / 125), inertia=inertia, n_cells=16)
        json.dumps(d, allow_nan=False)


def test_plot_dispersion_agg():
    ax = stab.plot_dispersion(Params(), inertia=True)
    assert len(ax.get_lines()) >= 3
    assert ax.get_xlabel().startswith("wavelength")
